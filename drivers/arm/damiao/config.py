"""The Damiao part of a robot config: each motor on the bus (model, ids, mounting), the joints and the gripper they
drive (limits, MIT gains), and the driver's watchdog. `drivers.arm.robot_config.RobotConfig` holds them.

Every limit is bounded so that an absurd finite one cannot switch a check off: a joint's v_max and tau_max within
its motor model's VMAX and TMAX, a_max and j_max within 10x the shipped configs' largest, the gripper's width
within MAX_GRIPPER_WIDTH_M; v_max, a_max and j_max have lower bounds too (a near-zero one makes every move last
longer than the trajectory planner can plan).
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationInfo, field_validator, model_validator

from drivers.arm.damiao.codec import PARAM_ID
from drivers.arm.damiao.motors import MODELS, MotorLimits

MAX_A_RAD_S2 = 200.0  # joint acceleration limit: 10x the shipped configs' largest (20)
MAX_J_RAD_S3 = 1e5  # joint jerk limit: 10x the shipped configs' largest (10000)
MIN_V_RAD_S, MIN_A_RAD_S2, MIN_J_RAD_S3 = 0.05, 0.1, 1.0  # slower: a full-range bring-up move outlasts Ruckig
MAX_GRIPPER_WIDTH_M = 0.3  # parallel grippers open 0.05-0.25 m; 80 is a width in mm given as m


class StrictModel(BaseModel):
    """A config section: unknown keys, non-finite numbers and changes after loading are refused."""

    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)


class MotorConfig(StrictModel):
    """One Damiao motor: model (for default limits), command id, feedback (master) id, mounting."""

    motor: str = "DM4310"
    can_id: int = Field(gt=0, lt=PARAM_ID)
    master_id: int = Field(ge=0, lt=PARAM_ID)
    direction: Literal[1, -1] = 1
    zero_offset: float = 0.0  # joint position (rad) where the motor reads 0: q_joint = direction * q_motor + offset

    @model_validator(mode="after")
    def _known_model(self) -> MotorConfig:
        if self.motor not in MODELS:
            raise ValueError(f"unknown motor model {self.motor!r}; known: {', '.join(MODELS)}")
        if self.master_id == self.can_id:
            raise ValueError(f"master_id must differ from can_id ({self.can_id})")
        return self

    @property
    def default_limits(self) -> MotorLimits:
        return MODELS[self.motor]

    @property
    def label(self) -> str:
        """How messages name it: "joint NAME" or "the gripper"."""
        return f"joint {self.name}"


class JointConfig(MotorConfig):
    """One arm joint: its URDF name, motor, limits (None = the URDF's) and MIT gains (normal and compliant)."""

    name: str
    q_min: float | None = None
    q_max: float | None = None
    v_max: float | None = Field(None, ge=MIN_V_RAD_S)  # rad/s
    a_max: float = Field(10.0, ge=MIN_A_RAD_S2, le=MAX_A_RAD_S2)  # rad/s^2
    j_max: float = Field(5000.0, ge=MIN_J_RAD_S3, le=MAX_J_RAD_S3)  # rad/s^3
    tau_max: float = Field(gt=0)
    kp: float = Field(30.0, ge=0, le=500)
    kd: float = Field(1.0, ge=0, le=5)
    kp_compliant: float = Field(5.0, ge=0, le=500)
    kd_compliant: float = Field(0.5, ge=0, le=5)

    @field_validator("v_max", "tau_max")
    @classmethod
    def _within_the_motor(cls, value: float | None, info: ValidationInfo) -> float | None:
        """v_max and tau_max within the motor model's VMAX and TMAX: a larger one is no limit at all."""
        model = MODELS.get(info.data.get("motor", ""))
        if value is None or model is None:
            return value
        bound, unit, register = (model.v_max, "rad/s", "VMAX") if info.field_name == "v_max" else \
            (model.t_max, "N m", "TMAX")
        if value > bound:
            raise ValueError(f"{info.field_name} {value:g} {unit} is above the {info.data['motor']}'s {register} "
                             f"{bound:g} {unit}: give at most that (or the motor model you have)")
        return value


class GripperConfig(MotorConfig):
    """A gripper driven by one Damiao motor: width = width_per_rad * (q_motor_joint - q_closed), in metres.

    `nm_per_newton` converts the requested grip force into the motor torque the driver allows (kp * error)."""

    max_width_m: float = Field(gt=0, le=MAX_GRIPPER_WIDTH_M)
    width_per_rad: float = Field(gt=0)
    q_closed: float = 0.0
    nm_per_newton: float = Field(0.01, gt=0)
    kp: float = Field(10.0, ge=0, le=500)
    kd: float = Field(0.5, ge=0, le=5)

    @property
    def name(self) -> str:
        """The gripper's motor is named "gripper" (`deploy arm zero --joint gripper`, motor reports)."""
        return "gripper"

    @property
    def label(self) -> str:
        return "the gripper"


class WatchdogConfig(StrictModel):
    """When the driver disables the motors: feedback older than `feedback_timeout_s`, a control cycle later than
    `max_late_cycles` periods, a parameter read unanswered after `reply_timeout_s` (per motor). When the motors
    disable themselves: no command for `motor_timeout_s` (each motor's communication timeout register, written
    and read back at enable), whatever became of the driver (a bus-off, a killed process, a pulled cable)."""

    feedback_timeout_s: float = Field(0.02, gt=0, le=1.0)
    max_late_cycles: float = Field(2.0, gt=0, le=1000)
    reply_timeout_s: float = Field(0.05, gt=0, le=1.0)
    torque_margin: float = Field(1.2, ge=1.0, le=5.0)  # measured |tau| above margin * tau_max is a fault
    stop_damping_s: float = Field(0.3, ge=0, le=5.0)  # stop(): damp (kp = 0) this long before disabling
    motor_timeout_s: float = Field(0.1, ge=0.005, le=1.0)  # the motors' own watchdog (50 us steps)
