"""Typed configuration: TOML files validated by pydantic, with CLI overrides on top.

A file holds any subset of the sections below; everything has a default, so no file is needed:

    [filter]            # radius outlier filter of the object cloud (profile "sim" or "sparse")
    profile = "sparse"  # default: follows the camera (simulation "sim", real cameras and recordings "sparse")
    radius_m = 0.013    # optional: the radius in metres (a unitless `radius` is refused)
    [geometry]
    box = "front"       # body box: "front" (turned to the front plane), "yaw" (paper) or "oriented" (3D)
    [estimator]
    name = "screw-grip"
    joint = "auto"
    [estimator.screw]   # registration and joint-fit settings of screw / screw-grip
    voxel_m = 0.005
    [opening]           # the opening policy: task, target, steps, speeds, gates, timeouts
    policy = "closed"
    drawer_step_m = 0.08
    [perception]        # segmenter prompts, models, first box, track-loss thresholds
    object_prompt = "cabinet"
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, ValidationError, field_validator, model_validator
from pydantic_core import PydanticCustomError

from deploy.errors import ConfigError
from deploy.geometry.estimators.registry import ESTIMATORS
from deploy.geometry.estimators.screw_config import ScrewConfig
from deploy.geometry.radius_filter import FILTER_PROFILES, FilterProfile
from deploy.geometry.types import JointType
from deploy.perception.config import PerceptionConfig
from deploy.policies import POLICIES, Fusion, OpeningPolicy, opening_policy
from drivers.toml_file import read_toml

Task = Literal["drawer", "door", "auto"]
CALIBRATION_ERROR = (5.0, 0.5)  # simulation: a field-grade hand-eye calibration's error, translation mm, rotation deg
NEAR_M = 0.1  # the nearest depth used when neither the config nor the camera says (m)



class _Section(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class FilterConfig(_Section):
    """Radius outlier filter: keep a point with at least `eps` other points within `radius_m` metres.

    `profile` fills in whichever of radius_m / eps is not given; None follows the camera (`Config.for_camera`):
    the paper's real-camera setting "sparse" (r = 1.3 cm, eps = 1) for real cameras and their recordings, its
    simulation setting "sim" (r = 0.05 m, eps = 100) in simulation (and where no camera is known). The radius is
    in metres whatever the profile: a unitless `radius` (and `unit`) is refused (`unitless_radius`).
    """

    profile: Literal["sim", "sparse"] | None = None
    radius_m: float | None = Field(default=None, gt=0, le=1.0, description="metres, whatever the profile")
    eps: int | None = Field(default=None, ge=1)

    def resolve(self) -> FilterProfile:
        """The setting used: the profile's (its radius with its unit), with radius_m and eps where given."""
        base = FILTER_PROFILES[self.profile or "sim"]
        eps = base.eps if self.eps is None else self.eps
        if self.radius_m is None:
            return FilterProfile(base.radius, eps, base.unit)
        return FilterProfile(self.radius_m, eps, "m")

    def used(self) -> dict:
        """The setting used, as the commands' JSON reports it: {"profile", "radius_m", "eps"}."""
        profile = self.resolve()
        return {"profile": self.profile, "radius_m": profile.radius_m, "eps": profile.eps}


def unitless_radius(data: dict[str, Any]) -> str | None:
    """The one-line fix when the `[filter]` table of a run's settings `data` has a unitless `radius` (whose
    unit followed the profile: the same number meant m in simulation and cm on a real camera) or `unit`."""
    section = data.get("filter")
    if not isinstance(section, dict) or not ({"radius", "unit"} & set(section)):
        return None
    radius, unit = section.get("radius"), section.get("unit")
    example = "radius_m = 0.013 for 1.3 cm"
    if isinstance(radius, (int, float)) and not isinstance(radius, bool) and unit in ("m", "cm", "mm"):
        metres = radius * {"m": 1.0, "cm": 0.01, "mm": 0.001}[unit]
        example = f"radius_m = {metres:g} for {radius:g} {unit}"
    return (f"filter.radius has no unit of its own (it followed the profile): give it in metres as "
            f"filter.radius_m ({example}) and drop filter.radius and filter.unit")


class GeometryConfig(_Section):
    """Body box and moving-part extraction.

    moving_part: "static-scene" (what left the first frame's static surfaces, inside the opening region:
    deploy/geometry/static_scene.py, with its own outlier filter; needs a fixed camera), "box" (the paper's: what
    left the first frame's body box, radius-filtered by `[filter]`) or "auto" (the estimator's own: "box" for
    paper-obb, "static-scene" for the others). `[filter]` also cleans the first frame's cloud for the body box.
    """

    moving_part: Literal["auto", "static-scene", "box"] = Field(
        default="auto", description="static-scene (what left the first frame's static surfaces), box (what left its "
        "body box: the paper's) or auto (box for paper-obb, static-scene otherwise)")
    box: Literal["front", "yaw", "oriented"] = Field(
        default="front", description="body box: front (vertical sides turned to the front face's plane), yaw (the "
        "paper's smallest top-view box) or oriented (3D)")
    remove_handle: bool = True
    body_margin_m: float = Field(default=0.01, ge=0, le=0.1)
    inside_depth_m: float = Field(
        default=1.0, ge=0, le=5, description="moving_part box, doors (estimator.joint revolute): the moving "
        "part is cut out by the body box reaching this far behind the front, because the cabinet's inside that an "
        "opening door reveals does not move (a drawer's revealed inside is the drawer)")
    min_depth_m: float | None = Field(
        default=None, ge=0, description="nearest depth used (m); unset: the camera's minimum range (its model's), "
        f"or {NEAR_M} m for a camera that does not say")
    max_depth_m: float = Field(default=3.0, gt=0)
    decimation: int = Field(default=2, ge=1, le=8, description="use every n-th pixel in each direction")

    @model_validator(mode="after")
    def _depth_range(self) -> GeometryConfig:
        if self.max_depth_m <= self.near_m:
            raise ValueError("max_depth_m must be larger than min_depth_m")
        return self

    @property
    def near_m(self) -> float:
        """The nearest depth used (m): `min_depth_m`, or NEAR_M where no camera set it (`Config.for_range`)."""
        return NEAR_M if self.min_depth_m is None else self.min_depth_m


def _registered(registry, name: str, error_type: str) -> str:
    """`name` when `registry` holds it, else a validation error in the registry's words ("unknown policy 'x': choose
    one of ...")."""
    try:
        registry.entry(name)
    except ConfigError as exc:
        raise PydanticCustomError(error_type, "{message}", {"message": str(exc)}) from None
    return name


class EstimatorConfig(_Section):
    """Which axis estimator runs, over how many frames, for which joint type; the screw estimators' settings.

    `screw-grip` fits the held handle's path as well when gripper poses come with the frames (a recording's
    ee_pose, or the closed loop with `opening.fusion` other than "vision"); without them it is `screw`.
    """

    name: str = Field(default="screw-grip", description="an estimator of the registry (`--estimator`)")
    joint: Literal["auto", "prismatic", "revolute"] = "auto"
    window: int = Field(default=10, ge=2, le=100)
    screw: ScrewConfig = ScrewConfig()

    @field_validator("name")
    @classmethod
    def _registered(cls, name: str) -> str:
        return _registered(ESTIMATORS, name, "unknown_estimator")


class OpeningConfig(_Section):
    """How to open: task, target (m for a drawer, deg for a door), policy and motion sizes.

    policy: a policy of the registry (deploy/policies.py): "closed" re-estimates after every step, "open" estimates
    once after the first pull and keeps that axis, "paper" runs the paper's straight steps with its estimator
    (`paper-obb`) on vision alone (the gripper's path and the force cue are ours, not the paper's).
    fusion: "vision" acts on the camera's estimate only; "trajectory" on a fit to the gripper's own path (FK) once
    it fits, vision before; "fused" on the trajectory fit once the gripper has moved `trajectory_min_travel` (m or
    deg) and the fit is confident, on vision otherwise and for the joint type; "force" on vision, except after a
    pull whose force across its path reached `force_cue_n` (the commanded axis was off and the compliant path
    yielded to the object): then on the fit to the gripper's path once it has moved `trajectory_min_travel`. A
    vision estimate below `vision_min_confidence` (doors: `door_vision_min_confidence`, and only past
    `vision_min_travel_deg`) is not acted on: the previous axis is kept, at first the prior from the first frame
    (drawer: the front normal; door: the front's far edge).
    """

    task: Task = "drawer"
    target_distance_m: float = Field(default=0.30, gt=0, le=1.0)
    target_angle_deg: float = Field(default=45.0, gt=0, le=170)
    policy: str = Field(default="closed", description="an opening policy of the registry (`--policy`)")
    fusion: Fusion = "force"
    force_cue_n: float = Field(default=10.0, gt=0, description="fusion force: a pull resisted across its path "
                               "by this much (N) was off the object's axis")
    first_pull_m: float = Field(default=0.05, gt=0, le=0.15, description="the handle's travel (m) before the "
                                "first estimate, less for a target nearer than that")
    probe_pull_m: float = Field(default=0.025, gt=0, le=0.1, description="task auto: straight pull that classifies")
    drawer_step_m: float = Field(default=0.08, gt=0, le=0.3)
    door_step_deg: float = Field(default=12.0, gt=0, le=45)
    trajectory_min_travel_m: float = Field(default=0.05, gt=0)
    trajectory_min_travel_deg: float = Field(default=10.0, gt=0)
    trajectory_min_confidence: float = Field(default=0.5, ge=0, le=1)
    vision_min_confidence: float = Field(default=0.5, ge=0, le=1)
    door_vision_min_confidence: float = Field(default=0.2, ge=0, le=1)
    vision_min_travel_deg: float = Field(default=20.0, ge=0, description="a door's vision axis is acted on "
                                         "from this opening on: a small turn leaves the hinge's position loose")
    max_steps: int = Field(default=12, ge=1)
    timeout_s: float = Field(default=90.0, gt=0, description="arm-clock seconds for the whole episode")
    camera_hz: float = Field(default=5.0, gt=0, le=60)
    approach_m: float = Field(default=0.10, gt=0, le=0.3)
    pull_speed_m_s: float = Field(default=0.08, gt=0, le=0.5)
    pull_speed_deg_s: float = Field(default=12.0, gt=0, le=90)
    min_mask_fraction: float = Field(default=0.2, gt=0, lt=1, description="tracking lost below this")
    pull_force_limit_n: float | None = Field(default=60.0, gt=0, le=500, description="a pull ends \"blocked\" "
                                             "when the force the tool applies (from the joint torques) exceeds "
                                             "this; a Panda-class arm's. None: no limit")

    @field_validator("policy")
    @classmethod
    def _registered(cls, name: str) -> str:
        return _registered(POLICIES, name, "unknown_policy")

    def strategy(self) -> OpeningPolicy:
        """The policy object `policy` names: what the episode acts with and how it steps."""
        return opening_policy(self.policy)

    @property
    def acting_fusion(self) -> Fusion:
        """The fusion the policy acts with: the policy's own (the paper's: "vision"), else `fusion`."""
        return self.strategy().acting_fusion(self.fusion)

    @property
    def target(self) -> float:
        """The target in SI units: metres (drawer) or radians (door)."""
        return self.target_distance_m if self.task != "door" else float(np.radians(self.target_angle_deg))

    def target_for(self, joint: JointType) -> float:
        """The target for `joint`: metres (prismatic) or radians (revolute)."""
        return self.target_distance_m if joint is JointType.PRISMATIC else float(np.radians(self.target_angle_deg))



class Config(_Section):
    """Everything a run reads: `[filter]`, `[geometry]`, `[estimator]` (with `[estimator.screw]`), `[opening]`
    and `[perception]`."""

    filter: FilterConfig = FilterConfig()
    geometry: GeometryConfig = GeometryConfig()
    estimator: EstimatorConfig = EstimatorConfig()
    opening: OpeningConfig = OpeningConfig()
    perception: PerceptionConfig = PerceptionConfig()

    @property
    def acting_estimator(self) -> str:
        """The estimator the policy acts with: the policy's own (the paper's: `paper-obb`), else `estimator.name`."""
        return self.opening.strategy().acting_estimator(self.estimator.name)

    def for_camera(self, camera: str) -> Config:
        """This config with the filter profile of camera `camera` (a registry spec) where none was chosen."""
        if self.filter.profile is not None:
            return self
        return self.replace(filter={"profile": filter_profile_for(camera)})

    def for_range(self, min_range_m: float | None) -> Config:
        """This config with `geometry.min_depth_m`, where unset, the camera's minimum range `min_range_m` (a
        `Camera.min_range_m`: depth nearer than it is not measured; None: the camera does not say)."""
        if self.geometry.min_depth_m is not None or min_range_m is None:
            return self
        if min_range_m >= self.geometry.max_depth_m:
            raise ConfigError(f"geometry.max_depth_m {self.geometry.max_depth_m:g} m lies within the camera's minimum "
                              f"range {min_range_m:g} m: set a larger geometry.max_depth_m")
        return self.replace(geometry={"min_depth_m": min_range_m})

    def replace(self, **sections: dict[str, Any]) -> Config:
        """A copy with fields of some sections changed and validated: `config.replace(opening={"task": "door"})`."""
        data = self.model_dump()
        for name, fields in sections.items():
            data[name].update(fields)
        return Config.model_validate(data)


def filter_profile_for(camera: str) -> Literal["sim", "sparse"]:
    """The filter profile for frames of camera `camera`: "sim" for a simulated camera or a recording made in
    simulation, "sparse" (the paper's real-camera setting) for a real camera and its recordings."""
    from drivers.camera.registry import simulated_source

    return "sim" if simulated_source(camera) else "sparse"


def _set_dotted(data: dict[str, Any], dotted: str, value: Any) -> None:
    *sections, key = dotted.split(".")
    for section in sections:
        data = data.setdefault(section, {})
    data[key] = value


def _numbers(data: Any, where: str = "") -> Iterator[tuple[str, float]]:
    """Every float in nested dicts and lists, with its dotted name."""
    if isinstance(data, float):
        yield where, data
    elif isinstance(data, dict):
        for key, value in data.items():
            yield from _numbers(value, f"{where}.{key}" if where else str(key))
    elif isinstance(data, (list, tuple)):
        for i, value in enumerate(data):
            yield from _numbers(value, f"{where}[{i}]")


def load_config(path: Path | None = None, overrides: dict[str, Any] | None = None,
                options: dict[str, str] | None = None) -> Config:
    """Load `path` (TOML) if given, apply `overrides` ({"filter.radius_m": 0.013, "opening.task": "door", ...};
    None values are skipped) and validate. Raises ConfigError naming the file, the field and the problem; a field
    set from a command-line option is named by `options` ({"opening.target_distance_m": "--distance"})."""
    data: dict[str, Any] = {}
    source = "command-line options"
    if path is not None:
        path = Path(path)
        source = str(path)
        if path.is_dir():
            raise ConfigError(f"config file {path} is a directory: give the path of a TOML file in it, or omit "
                              "--config to use defaults")
        if not path.is_file():
            raise ConfigError(f"config file {path} not found: check the path or omit --config to use defaults")
        data = _read_run_config(path)
    for dotted, value in (overrides or {}).items():
        if value is not None:
            _set_dotted(data, dotted, value)
    if (fix := unitless_radius(data)) is not None:
        raise ConfigError(f"invalid configuration in {source}: {fix}")
    for where, value in _numbers(data):
        if not math.isfinite(value):
            raise ConfigError(f"invalid configuration in {source}: {where} is {value}: give a finite number")
    try:
        return Config.model_validate(data)
    except ValidationError as exc:
        given = {dotted for dotted, value in (overrides or {}).items() if value is not None}
        named = {dotted: option for dotted, option in (options or {}).items() if dotted in given}
        problems = [_problem(err, named) for err in exc.errors()]
        if all(dotted in named for dotted, _ in problems):
            raise ConfigError("; ".join(text for _, text in problems)) from exc
        raise ConfigError(f"invalid configuration in {source}: {'; '.join(text for _, text in problems)}") from exc


def _read_run_config(path: Path) -> dict[str, Any]:
    """The tables of the TOML run config `path`; ConfigError naming the fix when it cannot be read, and saying so
    when it is JSON (by its suffix, or text TOML refuses and JSON reads): most likely a run's config.json."""
    example = "docs/quickstart.md#configuration shows the sections"
    if path.suffix.lower() != ".json":
        try:
            return read_toml(path, "config file", ConfigError, example)
        except ConfigError:
            if not _reads_as_json(path):
                raise
    raise ConfigError(f"config file {path} is JSON, not TOML: --config takes a TOML run config, not a run's record "
                      f"of the settings it used (RUN/config.json); write the settings to change in a .toml file "
                      f"({example}), or omit --config for the defaults")


def _reads_as_json(path: Path) -> bool:
    try:
        json.loads(path.read_text(encoding="utf-8-sig"))
    except (OSError, ValueError, RecursionError):
        return False
    return True


_OWN_FIX = {"unknown_estimator", "unknown_policy"}
"""Errors whose message already names the fix (the registry's "choose one of ...")."""


def _problem(err: Any, named: dict[str, str]) -> tuple[str, str]:
    """(dotted field, what is wrong with it): a field a command-line option set is named by the option."""
    dotted = ".".join(str(p) for p in err["loc"])
    if dotted in named and err["type"] in _OWN_FIX:
        return dotted, f"invalid value for {named[dotted]} ({dotted}): {err['msg']}"
    if dotted in named:
        return dotted, (f"invalid value for {named[dotted]}: {err['input']!r}: {err['msg'][0].lower()}"
                        f"{err['msg'][1:]} ({dotted}): give a value in that range")
    return dotted, f"{dotted}: {err['msg']}"
