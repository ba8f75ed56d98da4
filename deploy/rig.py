"""One place that builds a rig: camera, arm, segmenter and the camera's pose in the arm's base frame, for
`deploy open*`, `calibrate`, `record` and arm bring-up, in simulation and on hardware alike.

Kinds come from the registries (`--camera`, `--arm`, `--segmenter`); `check_spec` refuses pairings that cannot
work from the registry entries' properties (simulated, hardware), never from kind names. Arm bring-up
(`deploy arm ...`, deploy/arm_bringup.py) needs no camera: it builds the arm alone with `build_arm`, the
function every rig builds its arm with, and reaches the motors directly through the arm kind's bare bus
(`bare_bus`: the bus factory its registry entry names). When the camera is simulated the rig
builds the PyBullet scene both devices live in: an opening scenario (a cabinet, `SimScene`) or a calibration
scene (a ChArUco board on the tool or the table, `BoardScene`). The scene's ground truth (`Rig.world`) is for
evaluation and test set-up only: the rig hands the controller the camera, the arm, the kinematics and the
segmenter, never the world.

A camera whose frames do not carry their pose gets it from the hand-eye calibration: `--calibration FILE`, or
the file saved for this camera's serial and robot (`deploy calibrate hand-eye`). The simulated camera's pose
comes from a simulated calibration: the true pose off by `calibration_error` (translation mm, rotation deg)
in a random direction drawn from the scene's seed, as a field calibration is.
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Iterator
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from deploy.config import CALIBRATION_ERROR
from deploy.errors import CalibrationError, ConfigError
from deploy.perception.base import Segmenter
from deploy.perception.config import PerceptionConfig
from deploy.perception.registry import SEGMENTERS
from deploy.perception.registry import needs as segmenter_needs
from drivers.arm.base import Arm
from drivers.arm.kinematics import Kinematics
from drivers.arm.registry import ARMS
from drivers.arm.robot_config import PANDA_SIM_CONFIG, RobotConfig, load_robot_config
from drivers.arm.robots import PANDA_REACH, Reach
from drivers.camera.base import Camera
from drivers.camera.posed import PosedCamera
from drivers.camera.registry import CAMERAS
from drivers.errors import ArmError
from drivers.registry import Registry

if TYPE_CHECKING:
    from calibration.board import BoardConfig
    from deploy.perception.self_filter import SelfFilter
    from drivers.arm.can_bus import CanBus
    from sim_fallback.world import SimWorld

log = logging.getLogger(__name__)

SIM_SERIAL = "sim-d415"  # the simulated camera's serial, naming its calibration files


@dataclass(frozen=True)
class SimScene:
    """The simulated opening scenario (sim_fallback.scenes.scene_scenario): a drawer or a door in `world` ("kitchen",
    or "box": one cabinet in empty space), the `part` a user names (None: the seed picks a reachable one), in a
    kitchen a PartNet-Mobility object `object_id` of the folder `assets` (None: the seed's) loaded at `scale`
    ("real" or "native"); its joint in `condition` ("normal", "locked" or "stiff": 3x the friction); without `part`,
    the seed's part is one that opens at least `opening` (m or rad: the task's target). The controller is never told
    any of it."""

    task: Literal["drawer", "door"] = "drawer"
    seed: int = 0
    split: Literal["train", "test"] = "train"
    condition: Literal["normal", "locked", "stiff"] = "normal"
    world: str = "kitchen"
    part: str | None = None
    assets: Path | None = None
    object_id: str | None = None
    scale: str = "real"
    opening: float = 0.0

    def scenario(self, reach: Reach = PANDA_REACH):
        """The scenario it names, the target's grip in the arm's `reach` (SceneError or PartNetError, one line, when
        it cannot be built)."""
        from sim_fallback.scenes import scene_scenario

        return scene_scenario(self.world, self.task, self.seed, self.split, self.part, self.assets, self.object_id,
                              self.scale, self.condition, reach, self.opening)


@dataclass(frozen=True)
class BoardScene:
    """The simulated calibration scene: a ChArUco `board` on the tool (eye-to-hand, a fixed camera) or on the
    table (eye-in-hand, a wrist camera). `noise`: "d415" depth noise or "none"; `color_sigma` grey levels."""

    setup: Literal["eye-to-hand", "eye-in-hand"]
    board: BoardConfig
    seed: int = 0
    resolution: tuple[int, int] = (640, 480)
    depth_noise: bool = True
    color_sigma: float = 0.0


@dataclass(frozen=True)
class RigSpec:
    """What to open. camera / arm: registry specs (None: no such device); robot: config TOML (default: the
    simulated Panda's for simulated arms; required for hardware arms); can: [can] settings of the command line
    over the robot config's ((name, value) pairs); segmenter: registry name (None: none). camera_options go to the
    camera's factory (width, height, fps, ...)."""

    camera: str | None = "sim"
    arm: str | None = "sim"
    robot: Path | None = None
    can: tuple[tuple[str, Any], ...] = ()
    calibration: Path | None = None
    segmenter: str | None = None
    perception: PerceptionConfig = PerceptionConfig()
    scene: SimScene | BoardScene = SimScene()
    camera_options: dict[str, Any] = field(default_factory=dict)
    calibration_error: tuple[float, float] = CALIBRATION_ERROR


@dataclass
class Rig:
    """Open devices. `world`, `sim_camera` (simulation only) and `board` (a calibration scene's) are for evaluation
    and test set-up, never for the controller."""

    spec: RigSpec
    robot: RobotConfig
    kin: Kinematics
    camera: Camera | None = None
    arm: Arm | None = None
    segmenter: Segmenter | None = None
    serial: str | None = None
    world: SimWorld | None = None
    board: Any = None  # sim_fallback.board.CalibrationRig of a BoardScene
    sim_camera: Any = None  # the simulated camera behind `camera` (its truth images: evaluation only)

    @property
    def simulated(self) -> bool:
        return self.world is not None

    @property
    def real_arm(self) -> bool:
        """A physical arm: asked for before its first motion."""
        return self.spec.arm is not None and ARMS.entry(self.spec.arm)[0].hardware

    def self_filter(self) -> SelfFilter | None:
        """The filter of the arm's own pixels in this camera's frames (None without both)."""
        if self.camera is None or self.arm is None:
            return None
        from deploy.perception.self_filter import SelfFilter
        from drivers.arm.body import RobotBody

        return SelfFilter(RobotBody.from_robot(self.robot))


def check_spec(spec: RigSpec) -> None:
    """Refuse combinations that cannot work, before anything opens: ConfigError naming the fix."""
    camera = CAMERAS.entry(spec.camera)[0] if spec.camera is not None else None
    arm = ARMS.entry(spec.arm)[0] if spec.arm is not None else None
    if spec.segmenter is not None:
        SEGMENTERS.entry(spec.segmenter)
    if camera is not None and arm is not None and arm.simulated and not camera.simulated:
        replay = " (to replay a recording without hardware: --arm ideal --robot panda_sim --dry-run)" \
            if spec.camera.startswith("replay") else ""
        raise ConfigError(f"--arm {spec.arm} needs --camera {kinds(CAMERAS, simulated=True)} (a simulated arm "
                          f"cannot act on what a real camera sees): use --arm {kinds(ARMS, simulated=False)} with "
                          f"--camera {spec.camera}{replay}")
    if camera is not None and arm is not None and camera.simulated and not arm.simulated:
        raise ConfigError(f"--camera {spec.camera} needs a simulated arm (--arm {kinds(ARMS, simulated=True)}), not "
                          f"{spec.arm!r}: it cannot see --arm {spec.arm}, only the simulated world's arm")
    if arm is not None and not arm.simulated and spec.robot is None:
        raise _needs_robot(spec.arm)


def load_robot(arm: str | None, robot: Path | None, can: tuple[tuple[str, Any], ...] = ()) -> RobotConfig:
    """The robot config of arm kind `arm` (a registry spec): `robot`, or for other than a physical arm the simulated
    Panda's, with the command line's [can] settings `can` over its own. A physical arm never falls back to a
    simulation config: without `robot`, or with a CAN bus (after `can`) that is virtual, ConfigError naming the
    fix."""
    hardware = arm is not None and ARMS.entry(arm)[0].hardware
    if hardware and robot is None:
        raise _needs_robot(arm)
    config = load_robot_config(robot or PANDA_SIM_CONFIG).with_can(**dict(can))
    if hardware and can and config.can.virtual:
        raise ConfigError(f"--interface {config.can.interface} --channel {config.can.channel} is a virtual bus, where "
                          "no real motor is: --arm can drives a real arm; give your adapter's (`deploy arm find-port` "
                          "lists them), or use --arm sim-can for the simulated motors")
    if hardware:
        try:
            config.can.require_hardware(config.label)
        except ArmError as exc:
            raise ConfigError(str(exc)) from None
    return config


def _needs_robot(arm: str) -> ConfigError:
    simulated_motors = " or ".join(e.usage for e in ARMS.entries() if e.simulated and e.bus is not None)
    return ConfigError(f"--arm {arm} needs --robot CONFIG.toml: your arm's config (`--robot damiao_6dof` is the "
                       f"shipped template; docs/arm.md); without hardware, simulated motors answer on --arm "
                       f"{simulated_motors}")


def kinds(registry: Registry, simulated: bool) -> str:
    """The live kinds of `registry` that are simulated (or physical), as a user writes them: "sim or sim-can"."""
    return " or ".join(e.usage for e in registry.entries() if e.live and e.simulated == simulated)


def build_arm(kind: str, robot: RobotConfig, world: SimWorld | None = None) -> Arm:
    """The arm `kind` (a registry spec) names for `robot`, built, not enabled: a rig's (simulated kinds act in
    its `world`), or arm bring-up's on its own (no world: `sim-can` then drives unloaded simulated motors)."""
    return ARMS.open(kind, robot) if world is None else ARMS.open(kind, robot, world=world)


@contextmanager
def bare_bus(kind: str, robot: RobotConfig) -> Iterator[tuple[CanBus, Any]]:
    """The bus of arm `kind` with no arm on top, from the bus factory of its registry entry, and the simulated
    motors answering on it (None on hardware); both closed after. ArmError when the kind has no bus."""
    entry, _ = ARMS.entry(kind)
    if entry.bus is None:
        with_bus = " or ".join(e.usage for e in ARMS.entries() if e.bus is not None)
        raise ArmError(f"this command talks to the motors directly: it needs --arm {with_bus}, not {kind!r}")
    bus, motors = entry.load_bus()(robot)
    try:
        yield bus, motors
    finally:
        bus.close()
        if motors is not None:
            motors.close()


@contextmanager
def open_rig(spec: RigSpec) -> Iterator[Rig]:
    """Open what `spec` names (camera connected; arm built but not enabled: `with rig.arm:` or `connect()`);
    on leaving, stop the arm and release everything."""
    check_spec(spec)
    robot = load_robot(spec.arm, spec.robot, spec.can)
    with ExitStack() as stack:
        rig = Rig(spec, robot, robot.kinematics())
        camera_entry = CAMERAS.entry(spec.camera)[0] if spec.camera is not None else None
        if camera_entry is not None and camera_entry.simulated:
            _open_simulated(rig, stack)
        else:
            _open_hardware(rig, stack)
        if spec.segmenter is not None:
            rig.segmenter = SEGMENTERS.open(spec.segmenter, spec.perception)
        log.info("devices: camera %s (serial %s), arm %s, robot %r (%s), segmenter %s", spec.camera, rig.serial,
                 spec.arm, robot.name, spec.robot or PANDA_SIM_CONFIG, spec.segmenter)
        yield rig


def _open_simulated(rig: Rig, stack: ExitStack) -> None:
    spec = rig.spec
    if isinstance(spec.scene, BoardScene):
        board_rig = stack.enter_context(board_scene(spec.scene))
        rig.world, rig.board, camera = board_rig.world, board_rig, board_rig.camera
    else:
        from sim_fallback.world import SimWorld

        scene = spec.scene
        arm = rig.robot.robot_spec()  # the robot config's arm, parked by its reach
        rig.world = stack.enter_context(SimWorld(scene.scenario(arm.reach), robot=arm))
        sim_camera = rig.sim_camera = CAMERAS.open(spec.camera, world=rig.world, seed=scene.seed,
                                                   labels=_needs_labels(spec), **spec.camera_options)
        T_calibrated = simulated_calibration(sim_camera.T_base_camera, *spec.calibration_error,
                                             np.random.default_rng([scene.seed, 7]))
        camera = PosedCamera(sim_camera, lambda: T_calibrated.copy())
        log.info("camera pose: simulated calibration, the true pose off by %g mm and %g deg", *spec.calibration_error)
    rig.camera, rig.serial = camera, SIM_SERIAL
    if spec.arm is None:
        return
    rig.arm = build_arm(spec.arm, rig.robot, rig.world)
    stack.callback(rig.arm.disconnect)
    rig.kin = rig.arm.kin


def _needs_labels(spec: RigSpec) -> bool:
    """Whether the rig's segmenter reads the simulator's labels (an ablation): only then does the camera render them."""
    return spec.segmenter is not None and segmenter_needs(spec.segmenter, "labels")


def simulated_calibration(T_true: np.ndarray, translation_mm: float, rotation_deg: float,
                          rng: np.random.Generator) -> np.ndarray:
    """`T_true` (a camera pose, 4x4) as a calibration with the given error would report it: shifted by
    `translation_mm` and turned by `rotation_deg` about the camera's centre, each in a random direction."""
    from scipy.spatial.transform import Rotation

    shift, axis = rng.normal(size=3), rng.normal(size=3)
    T = np.array(T_true, float)
    T[:3, :3] = Rotation.from_rotvec(np.radians(rotation_deg) * axis / np.linalg.norm(axis)).as_matrix() @ T[:3, :3]
    T[:3, 3] += translation_mm / 1000 * shift / np.linalg.norm(shift)
    return T


def _open_hardware(rig: Rig, stack: ExitStack) -> None:
    """Camera first (its serial names the calibration file), then the arm (built, not enabled)."""
    spec = rig.spec
    camera = None
    if spec.camera is not None:
        camera = CAMERAS.open(spec.camera, **spec.camera_options)
        camera.connect()
        stack.callback(camera.disconnect)
        rig.serial = camera.serial or spec.camera
        rig.camera = camera
    if spec.arm is not None:
        rig.arm = build_arm(spec.arm, rig.robot)
        stack.callback(rig.arm.disconnect)
        rig.kin = rig.arm.kin
        if camera is not None:
            rig.camera = PosedCamera(camera, _calibrated_pose(rig), override=spec.calibration is not None)


def _calibrated_pose(rig: Rig) -> Callable[[], np.ndarray]:
    """T_base_camera for frames that do not carry it (all frames with --calibration): --calibration, or this
    camera's saved calibration; an eye-in-hand camera's at the arm's current tool pose."""
    from calibration.store import load_for, load_hand_eye

    spec, serial = rig.spec, rig.serial
    real_serial = serial if serial != spec.camera else None
    record = (load_hand_eye(spec.calibration) if spec.calibration is not None
              else load_for(real_serial, rig.robot.name) if real_serial else None)
    _log_calibration(rig, record)

    def pose() -> np.ndarray:
        if record is None:
            raise CalibrationError(
                f"no hand-eye calibration for camera {serial} on robot {rig.robot.name!r}: run "
                "`deploy calibrate hand-eye` or give --calibration FILE")
        return record.T_base_camera(rig.kin.fk(rig.arm.state().q))

    return pose


def _log_calibration(rig: Rig, record: Any) -> None:
    """Which hand-eye calibration gives the camera's pose (--verbose)."""
    from calibration.store import hand_eye_path

    if record is None:
        log.info("camera pose: no hand-eye calibration for camera %s on robot %r (frames must carry their pose)",
                 rig.serial, rig.robot.name)
        return
    where = rig.spec.calibration or hand_eye_path(record.camera_serial, record.robot_id)
    log.info("camera pose: hand-eye calibration %s (%s, camera %s, robot %r, %.0f days old)", where, record.setup,
             record.camera_serial, record.robot_id, record.age_days())


TEXTURE_PX_PER_M = 3000.0  # about 2 texels per image pixel where the board is nearest the camera
TEXTURE_MARGIN_M = 0.01


def board_scene(scene: BoardScene):
    """The simulated calibration scene (sim_fallback.board.CalibrationRig, a context manager) for `scene`."""
    from calibration.board import render_board
    from drivers.camera.depth_noise import DepthNoise
    from sim_fallback.board import BoardTexture, build_rig

    board = scene.board
    texture = BoardTexture(render_board(board, TEXTURE_PX_PER_M, TEXTURE_MARGIN_M), TEXTURE_PX_PER_M,
                           (-TEXTURE_MARGIN_M, -TEXTURE_MARGIN_M))
    return build_rig(scene.setup, texture, board.center_m, scene.resolution,
                     None if scene.depth_noise else DepthNoise.none(), scene.color_sigma, scene.seed)
