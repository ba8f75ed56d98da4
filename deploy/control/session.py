"""One `deploy open*` request: build the rig it names, run the episode, finish the run folder, return the JSON.

In simulation the scenario's truth scores the episode afterwards (`deploy.evaluation`) and, with --view, its
true axis is logged to the viewer before the episode; the controller never sees it. A real arm asks `confirm`
before its first motion unless --yes or --dry-run. The JSON names units in its keys (`opened_m` or
`opened_deg`) and reports the cloud filter used (`filter`: radius_m, eps).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from datetime import datetime
from pathlib import Path
from typing import Any, Literal

from deploy.config import CALIBRATION_ERROR, Config, load_config
from deploy.control.episode import run_episode
from deploy.control.view import EpisodeView, step_log
from deploy.errors import ConfigError
from deploy.geometry.types import JointType
from deploy.perception.base import Pointer
from deploy.perception.registry import default_segmenter
from deploy.report.run_folder import RunFolder
from deploy.rig import Rig, RigSpec, SimScene, load_robot, open_rig
from drivers.camera.registry import CAMERAS
from drivers.interrupts import Interrupted

log = logging.getLogger(__name__)

OPTIONS = {"opening.target_distance_m": "--distance", "opening.target_angle_deg": "--angle",
           "opening.policy": "--policy", "filter.profile": "--filter", "perception.object_prompt": "--prompt",
           "perception.box": "--box", "perception.point": "--point"}  # the options that set these fields (errors)
VIEW_FILE = "episode.rrd"  # the run folder's rerun recording, with --view
Setup = Callable[[Any, Any], None]  # (world, arm) -> None: changes a simulated world before the episode (tests)


@dataclass(frozen=True)
class OpenRequest:
    """What the user asked for. task: what the policy is told ("auto" = classify from the probe pull);
    scene: the simulated object's kind, in `world` (`--camera sim` only, as `part`, `assets`, `object_id`, `scale`
    and `condition`: `SimScene`); distance_m / angle_deg / policy: None keeps the config's; point: the pixel (u, v)
    the user points at on the part in the first frame (None: in simulation the simulated user's, on hardware
    none); config_file: a run's TOML (deploy/config.py); overrides: settings on top, by dotted name
    ({"opening.max_steps": 3, "filter.profile": "sparse", "perception.object_prompt": "drawer"}). The filter
    profile, unless set, follows the camera (`Config.for_camera`)."""

    task: Literal["drawer", "door", "auto"]
    scene: Literal["drawer", "door"] = "drawer"
    distance_m: float | None = None
    angle_deg: float | None = None
    camera: str = "sim"
    arm: str = "sim"
    robot: Path | None = None
    can: tuple[tuple[str, Any], ...] = ()  # [can] settings of the command line over the robot config's
    calibration: Path | None = None
    segmenter: str | None = None
    seed: int = 0
    split: Literal["train", "test"] = "train"
    policy: str | None = None  # a policy of the registry (deploy/policies.py); None keeps the config's
    run_dir: Path | None = None
    dry_run: bool = False
    yes: bool = False
    view: bool = False
    resolution: tuple[int, int] = (640, 480)
    calibration_error: tuple[float, float] = CALIBRATION_ERROR
    condition: Literal["normal", "locked", "stiff"] = "normal"  # the simulated object's joint (never told)
    world: str = "kitchen"
    part: str | None = None
    assets: Path | None = None
    object_id: str | None = None
    scale: str = "real"
    point: tuple[float, float] | None = None
    config_file: Path | None = None
    overrides: dict[str, Any] = field(default_factory=dict)

    def config(self) -> Config:
        point = {"perception.point": self.point} if self.point is not None else {}
        return load_config(self.config_file, {
            "opening.task": self.task, "opening.policy": self.policy, "opening.target_distance_m": self.distance_m,
            "opening.target_angle_deg": self.angle_deg, **point, **self.overrides}, OPTIONS).for_camera(self.camera)

    def sim_scene(self, config: Config) -> SimScene:
        """The simulated scene, its part one that opens as far as the opening asks (`SimScene.opening`)."""
        return SimScene(self.scene, self.seed, self.split, self.condition, self.world, self.part, self.assets,
                        self.object_id, self.scale, self.scene_opening(config))

    def scene_opening(self, config: Config) -> float:
        """How far the opening asks the simulated part (of kind `scene`) to open: m or rad."""
        return config.opening.target_for(JointType.PRISMATIC if self.scene == "drawer" else JointType.REVOLUTE)

    def rig_spec(self, config: Config) -> RigSpec:
        simulated = CAMERAS.entry(self.camera)[0].simulated
        width, height = self.resolution
        return RigSpec(camera=self.camera, arm=self.arm, robot=self.robot, can=self.can, calibration=self.calibration,
                       segmenter=self.segmenter or default_segmenter(config.perception),
                       perception=config.perception,
                       scene=self.sim_scene(config),
                       calibration_error=self.calibration_error,
                       camera_options={"width": width, "height": height, "fps": config.opening.camera_hz}
                       if simulated else {})

    def folder(self) -> Path:
        """`run_dir`, or a new folder under runs/ named by the task and the time, claimed so that runs started in
        the same second (parallel jobs) never share one."""
        if self.run_dir is not None:
            return self.run_dir
        stem = Path("runs") / f"{self.task}-{datetime.now():%Y%m%d-%H%M%S}"
        stem.parent.mkdir(parents=True, exist_ok=True)
        path, k = stem, 1
        while True:
            try:
                path.mkdir()
                return path
            except FileExistsError:
                k += 1
                path = stem.with_name(f"{stem.name}-{k}")


def check_request(request: OpenRequest) -> None:
    """ConfigError for an opening that cannot be carried out: one on a recording, which cannot show what the arm
    does (its episode would judge the recorded object by an arm that never held it), unless it is a dry run."""
    if not request.dry_run and not CAMERAS.entry(request.camera)[0].live:
        raise ConfigError(f"--camera {request.camera} is a recording: it cannot show what the arm does, so an "
                          "opening on it can only be planned: add --dry-run (without hardware: --arm ideal --robot "
                          "panda_sim --dry-run)")


def open_object(request: OpenRequest, confirm: Callable[[str], None] | None = None,
                setup: Setup | None = None, keep_run_dir: bool = True) -> dict:
    """Run the request; the episode's JSON result (simulation adds the truth-based fields).

    confirm(question) is asked before a real arm's first motion (it aborts by raising); setup(world, arm)
    changes a simulated world before the episode; keep_run_dir False: no run folder (benchmarks)."""
    wall = time.perf_counter()
    check_request(request)
    config = request.config()
    request = _with_object(request, config)
    run_dir = request.folder() if keep_run_dir else None
    with open_rig(request.rig_spec(config)) as rig:
        if setup is not None:
            setup(rig.world, rig.arm)
        evaluation = _evaluation(rig)
        config, pointer = _pointed(config, rig, evaluation, request.seed)
        _log_config(config)
        scene = _scene(request, rig, pointer)
        folder = None if run_dir is None else RunFolder(run_dir, request.camera, rig.simulated, config, scene,
                                                        rig.robot.reference)
        if rig.real_arm and confirm is not None and not (request.dry_run or request.yes):
            confirm(f"The arm will grasp and pull the {request.task} in view. Area clear, arm supervised?")
        view = _view(request, run_dir, evaluation, rig)
        with rig.arm:
            try:
                result = run_episode(rig.camera, rig.arm, rig.segmenter, config, rig.robot, folder, view,
                                     request.dry_run, rig.self_filter())
            except Interrupted as stop:  # Ctrl-C / SIGTERM: finish the run folder up to here, then stop (later
                # signals are only recorded now, drivers/interrupts.py: a second Ctrl-C cannot cut the folder short)
                if folder is not None and stop.result is not None:
                    folder.finish(stop.result, evaluation.axis_error if evaluation is not None else None,
                                  rig.arm.motor_states())
                    stop.run_dir = folder.path
                raise
        data = {**result.to_dict(), "task": request.task, "camera": request.camera,
                "arm": request.arm, "policy": config.opening.policy, "segmenter": rig.spec.segmenter,
                "filter": config.filter.used(), **scene}
        if motors := rig.arm.motor_states():
            data["motors"] = motors
        if (rrd := view.saved_to()) is not None:
            data["rrd"] = rrd
        if evaluation is not None:
            translation_mm, rotation_deg = request.calibration_error
            data.update({"seed": request.seed, "split": request.split, "task": request.scene,
                         "calibration_error": {"translation_mm": translation_mm, "rotation_deg": rotation_deg},
                         **evaluation.score(result, config.opening), "seconds": time.perf_counter() - wall})
    if folder is not None:
        folder.finish(result, evaluation.axis_error if evaluation is not None else None, data.get("motors"))
    return data


def _with_object(request: OpenRequest, config: Config) -> OpenRequest:
    """`request` with the PartNet-Mobility object its seed opens, when it gives --assets without --object."""
    if request.assets is None or request.object_id is not None or not CAMERAS.entry(request.camera)[0].simulated:
        return request
    from sim_fallback.scenes import task_objects

    reach = load_robot(request.arm, request.robot).reach.reach()
    objects = task_objects(request.assets, request.scene, request.scale, reach, request.scene_opening(config))
    return replace(request, object_id=objects.for_seed(request.seed))


def _pointed(config: Config, rig: Rig, evaluation: Any, seed: int) -> tuple[Config, dict | None]:
    """`config` with the pixel the user points at: --point (or the config's; refused off the camera's image), else in
    a simulated kitchen the simulated user's on the target part's front (said on the step log), else none (the box
    world, hardware); and the pointer as the run records it (u, v, source)."""
    point = config.perception.point
    intrinsics = rig.camera.intrinsics if rig.camera is not None else None
    if point is not None and intrinsics is not None and not Pointer.of(point).inside(intrinsics.width,
                                                                                     intrinsics.height):
        raise ConfigError(f"--point {point[0]:g} {point[1]:g} is off the camera's {intrinsics.width}x"
                          f"{intrinsics.height} image: give the pixel (U from 0 to {intrinsics.width - 1}, V from 0 to "
                          f"{intrinsics.height - 1}) of the part to open in the first frame")
    if point is not None:
        return config, {"u": point[0], "v": point[1], "source": "--point"}
    if evaluation is not None and rig.world.scenario.world == "box":  # the paper's setting: one cabinet in empty
        # space, found without a pointer (today's pipeline, the ablation)
        return config, None
    user = evaluation.user_point(rig.sim_camera, seed) if evaluation is not None else None
    if user is None:
        if evaluation is not None:
            step_log.info("the simulated user sees no pixel of the target part: the controller gets no pointer")
        return config, None
    step_log.info("the simulated user points at pixel (%d, %d) on the target part (give --point U V to choose)",
                  *user)
    return config.replace(perception={"point": user}), {"u": user[0], "v": user[1], "source": "simulated user"}


def _scene(request: OpenRequest, rig: Rig, pointer: dict | None) -> dict:
    """What the run folder and the JSON record of the scene: the pointer, and in simulation the world, the
    furniture (with --assets: the folder, object and scale), the part and the sensor models in force."""
    out: dict[str, Any] = {"pointer": pointer}
    if rig.world is None:
        return out
    from sim_fallback.devices import sensor_models
    from sim_fallback.scenes import scenario_object

    scenario = rig.world.scenario
    assets = request.assets is not None
    return {**out, "world": scenario.world, "furniture": scenario_object(scenario),
            "assets": str(request.assets) if assets else None,
            "object": request.object_id,
            "scale": request.scale if assets else None, "part": scenario.part,
            "sensors": sensor_models(rig.sim_camera, rig.robot, request.seed)}


def _log_config(config: Config) -> None:
    """The resolved run config, for --verbose."""
    o, e = config.opening, config.estimator
    target = (f"{o.target_distance_m:g} m" if o.task == "drawer" else f"{o.target_angle_deg:g} deg" if o.task == "door"
              else f"{o.target_distance_m:g} m or {o.target_angle_deg:g} deg")
    log.info("run config: filter %s (%s); estimator %s, joint %s, window %d; opening %s to %s, policy %s, fusion "
             "%s, max %d steps, timeout %g s; prompt %r, box %s, point %s", config.filter.profile,
             config.filter.resolve(), config.acting_estimator, e.joint, e.window, o.task, target, o.policy,
             o.acting_fusion, o.max_steps, o.timeout_s,
             config.perception.object_prompt, config.perception.box, config.perception.point)


def _evaluation(rig: Rig):
    if rig.world is None:
        return None
    from deploy.evaluation import Evaluation

    return Evaluation(rig.world)


def _view(request: OpenRequest, run_dir: Path | None, evaluation: Any, rig: Rig) -> EpisodeView:
    """The episode's step lines, and with --view the rerun viewer (RUN/episode.rrd) showing the robot from its URDF
    and, in simulation, the true axis too."""
    viewer = None
    if request.view and run_dir is not None:
        from deploy.report.viewer import RerunViewer

        viewer = RerunViewer(run_dir / VIEW_FILE)
        viewer.robot(rig.robot.urdf_path(), rig.robot.joint_names, rig.robot.locked_joints)
    view = EpisodeView(viewer)
    if evaluation is not None:
        view.true_axis(evaluation.true_axis())
    return view
