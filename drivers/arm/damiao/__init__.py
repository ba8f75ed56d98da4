"""Damiao motors (MIT mode over CAN), one folder per motor family as LeRobot keeps them:

- codec.py   the frames: pure functions from values to CAN payloads and back (commands, feedback, parameters);
- motors.py  the motor models and the ranges their frames map onto (PMAX, VMAX, TMAX);
- config.py  the Damiao part of a robot config: motors, the joints and gripper they drive, the driver's watchdog.

The driver that talks to them is the CAN arm (drivers/arm/can_arm.py, over can_bus.py and motor_channels.py).
"""

from drivers.arm.damiao.codec import (
    FRAME_LEN,
    INTEGER_REGISTERS,
    KD_MAX,
    KP_MAX,
    PARAM_ID,
    PARAM_READ,
    PARAM_WRITE,
    REFRESH,
    REG_MST_ID,
    REG_PMAX,
    REG_TIMEOUT,
    REG_TMAX,
    REG_VMAX,
    TIMEOUT_UNIT_S,
    Feedback,
    FrameError,
    ParamReply,
    Special,
    Status,
    is_param_reply,
    is_special,
    pack_feedback,
    pack_mit,
    pack_param_reply,
    param_read,
    param_value_bytes,
    param_write,
    refresh_request,
    special,
    timeout_steps,
    unpack_feedback,
    unpack_mit,
    unpack_param_reply,
    unpack_param_request,
)
from drivers.arm.damiao.motors import MODELS, MotorLimits

__all__ = [
    "FRAME_LEN", "INTEGER_REGISTERS", "KD_MAX", "KP_MAX", "MODELS", "PARAM_ID", "PARAM_READ", "PARAM_WRITE",
    "REFRESH", "REG_MST_ID", "REG_PMAX", "REG_TIMEOUT", "REG_TMAX", "REG_VMAX", "TIMEOUT_UNIT_S", "Feedback",
    "FrameError", "MotorLimits", "ParamReply", "Special", "Status", "is_param_reply", "is_special", "pack_feedback",
    "pack_mit", "pack_param_reply", "param_read", "param_value_bytes", "param_write", "refresh_request", "special",
    "timeout_steps", "unpack_feedback", "unpack_mit", "unpack_param_reply", "unpack_param_request",
]
