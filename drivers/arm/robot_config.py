"""Robot config (TOML, validated with pydantic): URDF, frames, CAN bus, per-joint motors, limits, gains, gripper,
compliance and grip force; the free-space motion limits of any arm come from it (`motion_limits`).

Every number must be finite (nan or inf in a limit, the workspace or a timeout would switch a safety check off),
and every limit is bounded so that an absurd finite one cannot switch a check off either: the workspace box within
WORKSPACE_REACH_M of the base, the control rate at least MIN_CONTROL_RATE_HZ, the watchdog's timeouts, and the
joints' and gripper's limits as drivers/arm/damiao/config.py bounds them. q_ready lies within the joint limits.
The configs shipped with the package (drivers/arm/configs/*.toml, `--robot panda_sim`, `--robot damiao_6dof`) are
complete examples; docs/arm.md describes every field.
"""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path
from typing import Annotated

import numpy as np
import pybullet_data
from pydantic import Field, ValidationError, model_validator

from drivers.arm.base import GRIP_FORCE_N
from drivers.arm.damiao.config import GripperConfig, JointConfig, MotorConfig, StrictModel, WatchdogConfig
from drivers.arm.kinematics import Kinematics
from drivers.arm.motion import Compliance
from drivers.arm.robots import Reach, RobotSpec
from drivers.arm.safety import SafetyGuard, SafetyLimits
from drivers.arm.trajectory import MotionLimits
from drivers.errors import ArmError
from drivers.toml_file import read_toml

WORKSPACE_REACH_M = 3.0  # |coordinate| of the workspace box (m, base frame); arms reach 0.5-1.8 m
MIN_CONTROL_RATE_HZ = 100.0  # a safety check at least every 10 ms
MAX_GRIP_FORCE_N = 500.0  # parallel grippers squeeze 20-200 N

WorkspaceCorner = Annotated[list[Annotated[float, Field(ge=-WORKSPACE_REACH_M, le=WORKSPACE_REACH_M)]],
                            Field(min_length=3, max_length=3)]


class CanConfig(StrictModel):
    """The CAN channel: python-can interface (socketcan, virtual, pcan, slcan, ...), bitrate, CAN FD."""

    interface: str = "socketcan"
    channel: str = "can0"
    bitrate: int = Field(1_000_000, gt=0)
    fd: bool = False
    data_bitrate: int = Field(5_000_000, gt=0)

    @property
    def virtual(self) -> bool:
        """No hardware is on this bus: python-can's in-process `virtual` interface or a Linux `vcan` link."""
        return self.interface == "virtual" or (self.interface == "socketcan" and
                                               re.fullmatch(r"vcan\d*", self.channel) is not None)

    def require_hardware(self, config: str) -> None:
        """ArmError when this bus is virtual: a real arm's command must reach the real bus or refuse."""
        if self.virtual:
            raise ArmError(f"{config} puts its CAN bus on interface {self.interface!r}, channel {self.channel!r}, "
                           "where no real motor is: --arm can drives a real arm, so give your arm's config (--robot "
                           "FILE with [can] interface = \"socketcan\" ...; docs/arm.md), or use --arm sim-can for "
                           "the simulated motors")


class ComplianceConfig(StrictModel):
    """How the arm's pulls yield to the object they hold (`drivers.arm.motion.Compliance`): the admittance's
    stiffness and damping, the largest offset from the commanded path, the force deadband below which nothing
    yields, and the time constant of the wrench filter (joint torques, `drivers.arm.wrench`)."""

    stiffness_n_per_m: float = Field(1000.0, ge=0, le=1e5)
    damping_n_s_per_m: float = Field(8000.0, gt=0, le=1e6)
    max_offset_m: float = Field(0.03, ge=0, le=0.1)
    deadband_n: float = Field(3.0, ge=0, le=50)
    filter_time_constant_s: float = Field(0.01, ge=0, le=1.0)

    def gains(self) -> Compliance:
        return Compliance(self.stiffness_n_per_m, self.damping_n_s_per_m, self.max_offset_m, self.deadband_n,
                          self.filter_time_constant_s)


class ReachConfig(StrictModel):
    """Where simulated scenes put the grip of the part to open, in the base frame (m): its horizontal distance from
    the base and its height above it, per task (`drivers.arm.robots.Reach`; defaults: the Panda's usual bands);
    `drawer_pull_m` the pull the drawer bands are set for; the
    `low_*` bands where the arm grasps a low handle from above (default: none); `model`: the robot config whose
    kinematics check a scene's parking (default: none, the bands alone)."""

    drawer_distance_m: tuple[float, float] = Reach.drawer_distance_m
    drawer_height_m: tuple[float, float] = Reach.drawer_height_m
    door_distance_m: tuple[float, float] = Reach.door_distance_m
    door_height_m: tuple[float, float] = Reach.door_height_m
    drawer_pull_m: float = Field(Reach.drawer_pull_m, ge=0.0)
    low_drawer_distance_m: tuple[float, float] | None = None
    low_drawer_height_m: tuple[float, float] | None = None
    low_door_distance_m: tuple[float, float] | None = None
    low_door_height_m: tuple[float, float] | None = None
    model: str | None = None

    @model_validator(mode="after")
    def _bands(self) -> ReachConfig:
        for key, band in self:
            if band is None or key in ("model", "drawer_pull_m"):
                continue
            lo, hi = band
            if lo > hi:
                raise ValueError(f"reach.{key}: the band's low end {lo:g} is above its high end {hi:g}")
        for task in ("drawer", "door"):
            if (getattr(self, f"low_{task}_distance_m") is None) != (getattr(self, f"low_{task}_height_m") is None):
                raise ValueError(f"reach: low_{task}_distance_m and low_{task}_height_m come together (the bands where "
                                 f"the arm grasps a low {task} from above): give both, or neither")
        return self

    def reach(self) -> Reach:
        return Reach(**dict(self))


class RobotConfig(StrictModel):
    """A whole arm. `urdf` is a path (relative to the config file) or `pybullet_data:<relative path>`."""

    name: str
    urdf: str
    base_frame: str
    tool_frame: str
    locked_joints: list[str] = []
    finger_joint_per_m: list[float] | None = None  # each locked (finger) joint per metre of opening; None: 0.5 each
    q_ready: list[float]
    q_start: list[float] | None = None  # where simulated scenes start the arm (None: q_ready)
    workspace_min: WorkspaceCorner
    workspace_max: WorkspaceCorner
    control_rate_hz: float = Field(500.0, ge=MIN_CONTROL_RATE_HZ, le=2000)
    gravity_compensation: bool = False  # MIT torque feed-forward from the URDF's inertias
    can: CanConfig = CanConfig()
    watchdog: WatchdogConfig = WatchdogConfig()
    compliance: ComplianceConfig = ComplianceConfig()
    reach: ReachConfig = ReachConfig()
    grip_force_n: float = Field(GRIP_FORCE_N, gt=0, le=MAX_GRIP_FORCE_N)  # the squeeze a grasp closes with
    joints: list[JointConfig] = Field(min_length=1)
    gripper: GripperConfig | None = None
    source: Path | None = None  # the file it was read from (set by load_robot_config)

    @model_validator(mode="after")
    def _consistent(self) -> RobotConfig:
        for key in ("q_ready", "q_start"):
            values = getattr(self, key)
            if values is not None and len(values) != len(self.joints):
                raise ValueError(f"{key} has {len(values)} values for {len(self.joints)} joints")
        if self.finger_joint_per_m is not None and len(self.finger_joint_per_m) != len(self.locked_joints):
            raise ValueError(f"finger_joint_per_m has {len(self.finger_joint_per_m)} values for "
                             f"{len(self.locked_joints)} locked_joints: give one per finger joint")
        if any(lo >= hi for lo, hi in zip(self.workspace_min, self.workspace_max, strict=True)):
            raise ValueError("workspace_min must be below workspace_max on every axis")
        for key in ("can_id", "master_id"):
            ids = [getattr(m, key) for m in self.motors]
            if len(set(ids)) != len(ids):
                raise ValueError(f"two motors share a {key}: {ids}")
        self._master_ids_apart()
        late_s = (self.watchdog.max_late_cycles + 1) / self.control_rate_hz
        if self.watchdog.motor_timeout_s <= late_s:
            raise ValueError(f"watchdog.motor_timeout_s {self.watchdog.motor_timeout_s:g} s would disable the motors "
                             f"between two commands of a running arm (a cycle may come {late_s:g} s after the last "
                             "at this control rate and max_late_cycles): give more")
        for j, q in zip(self.joints, self.q_ready, strict=True):
            if j.q_min is not None and j.q_max is not None and j.q_min >= j.q_max:
                raise ValueError(f"joint {j.name}: q_min must be below q_max")
            for bound, outside in (("q_min", j.q_min is not None and q < j.q_min),
                                   ("q_max", j.q_max is not None and q > j.q_max)):
                if outside:
                    raise ValueError(f"q_ready of joint {j.name} is {q:g} rad, beyond its {bound} "
                                     f"{getattr(j, bound):g} rad: give q_ready in radians within q_min..q_max")
        return self

    def _master_ids_apart(self) -> None:
        """No motor's master (feedback) id is another's can_id: its feedback would reach that motor as commands."""
        by_can_id = {m.can_id: m.label for m in self.motors}
        for m in self.motors:
            if m.master_id in by_can_id:
                raise ValueError(f"{m.label}'s master_id {m.master_id:#x} is {by_can_id[m.master_id]}'s "
                                 f"can_id: its feedback would reach {by_can_id[m.master_id]} as commands; give "
                                 "every motor a master_id no motor uses as can_id (e.g. can_id + 0x10)")

    def with_can(self, **settings) -> RobotConfig:
        """This config with [can] settings replaced (interface, channel, bitrate, fd, data_bitrate: the command
        line's); ArmError naming a bad one."""
        if not settings:
            return self
        try:
            can = CanConfig.model_validate({**self.can.model_dump(), **settings})
        except ValidationError as exc:
            raise ArmError(f"CAN settings {settings}: {_problems(exc)}: fix the option") from exc
        return self.model_copy(update={"can": can})

    @property
    def label(self) -> str:
        """`robot config FILE` (or the config's name when it was not read from a file), for error messages."""
        return f"robot config {self.source}" if self.source else f"robot config {self.name!r}"

    @property
    def control_period_s(self) -> float:
        return 1.0 / self.control_rate_hz

    @property
    def joint_names(self) -> list[str]:
        return [j.name for j in self.joints]

    @property
    def motors(self) -> list[MotorConfig]:
        """Every motor on the bus: the joints', then the gripper's."""
        return [*self.joints, *([self.gripper] if self.gripper else [])]

    @property
    def reference(self) -> str:
        """How to name this config again (`--robot`, recordings' meta.json): a shipped config's name, else its file
        (its name when it was not read from one)."""
        if self.source is None:
            return self.name
        return self.source.stem if self.source.parent == CONFIG_DIR else str(self.source)

    def urdf_path(self) -> Path:
        if self.urdf.startswith("pybullet_data:"):
            return Path(pybullet_data.getDataPath()) / self.urdf.removeprefix("pybullet_data:")
        path = Path(self.urdf)
        return path if path.is_absolute() or self.source is None else self.source.parent / path

    def robot_spec(self) -> RobotSpec:
        """The RobotSpec the shared kinematics, motion and safety code take."""
        width = self.gripper.max_width_m if self.gripper else 0.0
        return RobotSpec(
            name=self.name, urdf=self.urdf_path(), arm_joints=tuple(self.joint_names),
            finger_joints=tuple(self.locked_joints), tool_frame=self.tool_frame, q_ready=np.array(self.q_ready),
            finger_joint_per_m=tuple(self.finger_joint_per_m or [0.5] * len(self.locked_joints)),
            q_start=None if self.q_start is None else np.array(self.q_start),
            gripper_max_width_m=width, a_max=np.array([j.a_max for j in self.joints]),
            j_max=np.array([j.j_max for j in self.joints]), workspace_min=np.array(self.workspace_min),
            workspace_max=np.array(self.workspace_max), reach=self.reach.reach(),
        )

    def kinematics(self) -> Kinematics:
        """Pinocchio kinematics of the URDF with the locked joints removed; checks joints, frames, the joint
        limits and q_ready against the URDF."""
        kin = Kinematics.from_robot(self.robot_spec())
        if kin.joint_names != self.joint_names:
            raise ArmError(f"{self.label}: joints {self.joint_names} do not match the URDF's movable "
                           f"joints {kin.joint_names}: list them in URDF order, lock the others (locked_joints)")
        if not kin.model.existFrame(self.base_frame):
            raise ArmError(f"{self.label}: base frame {self.base_frame!r} is not in the URDF")
        limits = self.safety_limits(kin)
        for j, q, lo, hi in zip(self.joints, self.q_ready, limits.q_min, limits.q_max, strict=True):
            if not lo <= q <= hi:
                raise ArmError(f"{self.label}: q_ready of joint {j.name} is {q:g} rad, outside its limits "
                               f"[{lo:.3f}, {hi:.3f}] rad (the URDF's narrowed by the config's): give q_ready in "
                               "radians within them")
        return kin

    def safety_limits(self, kin: Kinematics) -> SafetyLimits:
        """URDF limits narrowed by the config's per-joint limits; ArmError naming the joint whose config range
        lies outside the URDF's."""
        q_min, q_max, v_max = kin.q_min, kin.q_max, kin.v_max
        for i, j in enumerate(self.joints):
            lo = q_min[i] if j.q_min is None else max(q_min[i], j.q_min)
            hi = q_max[i] if j.q_max is None else min(q_max[i], j.q_max)
            if lo >= hi:
                raise ArmError(f"{self.label}: joint {j.name}'s range [{j.q_min}, {j.q_max}] rad lies outside the "
                               f"URDF's [{q_min[i]:.3f}, {q_max[i]:.3f}] rad: give q_min and q_max within it (in "
                               "radians) or omit them to use the URDF's")
            q_min[i], q_max[i] = lo, hi
            v_max[i] = v_max[i] if j.v_max is None else min(v_max[i], j.v_max)
        return SafetyLimits(q_min, q_max, v_max, np.array([j.a_max for j in self.joints]),
                            np.array(self.workspace_min), np.array(self.workspace_max))

    def safety_guard(self, kin: Kinematics) -> SafetyGuard:
        """The check every command of an arm of this config passes (`safety_limits`)."""
        return SafetyGuard(self.safety_limits(kin), self.joint_names)

    def motion_limits(self, kin: Kinematics, fraction: float) -> MotionLimits:
        """The free-space motion limits of any arm of this config, the one place they are computed: `fraction` of
        the safety limits (URDF narrowed by the config) and of the joints' jerk limits, so planned moves never
        trip the safety layer."""
        safety = self.safety_limits(kin)
        return MotionLimits(safety.v_max * fraction, safety.a_max * fraction, self.robot_spec().j_max * fraction)


def shipped_robot_configs() -> list[str]:
    """The names of the robot configs shipped with the package (`--robot NAME`)."""
    return sorted(p.stem for p in CONFIG_DIR.glob("*.toml"))


def robot_config_path(spec: str | Path) -> Path:
    """The file `spec` names: an existing path, else a shipped config's name (`panda_sim`, `damiao_6dof`).
    ArmError naming both choices otherwise."""
    path = Path(spec)
    if path.is_file():
        return path
    shipped = CONFIG_DIR / f"{spec}.toml"
    if path.parent == Path(".") and not path.suffix and shipped.is_file():
        return shipped
    raise ArmError(f"robot config {spec} not found: give the path of a TOML file or a shipped config's name "
                   f"({', '.join(shipped_robot_configs())})")


@lru_cache(maxsize=1)
def panda_sim_config() -> RobotConfig:
    """The simulated Panda's robot config (read once): the limits and grip force of the simulated world's arm."""
    return load_robot_config(PANDA_SIM_CONFIG)


def load_robot_config(spec: str | Path) -> RobotConfig:
    """Read and validate a robot config (a path, or a shipped config's name); ArmError naming the file and the
    bad field otherwise."""
    path = robot_config_path(spec)
    data = read_toml(path, "robot config", ArmError, "`deploy arm status --robot damiao_6dof` uses a shipped example")
    try:
        return RobotConfig.model_validate({**data, "source": path.resolve()})
    except ValidationError as exc:
        raise ArmError(f"robot config {path}: {_problems(exc)}: fix the field (docs/arm.md lists them)") from exc


def _problems(exc: ValidationError, shown: int = 3) -> str:
    """The first `shown` problems of `exc` (unknown keys first: a misspelt key also leaves its field missing)."""
    errors = sorted(exc.errors(), key=lambda e: e["type"] != "extra_forbidden")
    texts = [": ".join(filter(None, (".".join(str(x) for x in e["loc"]), e["msg"]))) for e in errors[:shown]]
    more = f" (and {len(errors) - shown} more)" if len(errors) > shown else ""
    return "; ".join(texts) + more


CONFIG_DIR = Path(__file__).resolve().parent / "configs"
"""The robot configs shipped with the package (package data)."""
PANDA_SIM_CONFIG = CONFIG_DIR / "panda_sim.toml"
"""The simulated Franka Panda's robot config (the default robot of the simulated arms)."""
