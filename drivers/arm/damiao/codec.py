"""Damiao motor protocol in MIT mode: pure functions from values to CAN payloads and back.

Frames (8-byte payloads, the same on classic CAN and on CAN FD):
- command on the motor's CAN id: q uint16 over [-PMAX, PMAX], dq uint12 over [-VMAX, VMAX], kp uint12 over
  [0, 500], kd uint12 over [0, 5], tau uint12 over [-TMAX, TMAX]
  (D0 = q>>8, D1 = q&FF, D2 = dq>>4, D3 = (dq&F)<<4 | kp>>8, D4 = kp&FF, D5 = kd>>4, D6 = (kd&F)<<4 | tau>>8,
  D7 = tau&FF); enable / disable / set zero / clear error = FF x7 then FC / FD / FE / FB.
- feedback on the master id: D0 = status<<4 | (CAN id & F), q = D1<<8|D2, dq = D3<<4|D4>>4,
  tau = (D4&F)<<8|D5, D6 = MOS temperature, D7 = rotor temperature (deg C).
- parameter read on 0x7FF: [id lo, id hi, 0x33, register, 0, 0, 0, 0]; write: [id lo, id hi, 0x55, register,
  value]; the answer comes on the master id as [id lo, id hi, 0x33 or 0x55, register, value] (value: little-endian
  float32, or uint32 for integer registers).

Values map onto their unsigned fields by truncation, as the Damiao manual's reference code and the OpenArm vendor
library (openarm_can `CanPacketEncoder`) do, so that a command's frame is the vendor's byte for byte
(tests/test_damiao_vendor.py); a simulated motor's feedback rounds to the nearest step.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from enum import IntEnum

from drivers.arm.damiao.motors import MotorLimits

PARAM_ID = 0x7FF
KP_MAX, KD_MAX = 500.0, 5.0
PARAM_READ, PARAM_WRITE, REFRESH = 0x33, 0x55, 0xCC
REG_MST_ID = 7
REG_TIMEOUT = 9  # communication timeout: no command for this long and the motor disables itself; 0 = never
TIMEOUT_UNIT_S = 50e-6  # one step of REG_TIMEOUT
REG_PMAX, REG_VMAX, REG_TMAX = 21, 22, 23
INTEGER_REGISTERS = frozenset({*range(7, 11), *range(13, 17), 35, 36})
FRAME_LEN = 8


class Special(IntEnum):
    """Last byte of the FF x7 special commands."""

    ENABLE = 0xFC
    DISABLE = 0xFD
    SET_ZERO = 0xFE
    CLEAR_ERROR = 0xFB


class Status(IntEnum):
    """Motor status in the high nibble of feedback byte 0."""

    DISABLED = 0x0
    ENABLED = 0x1
    OVER_VOLTAGE = 0x8
    UNDER_VOLTAGE = 0x9
    OVER_CURRENT = 0xA
    MOS_OVER_TEMPERATURE = 0xB
    COIL_OVER_TEMPERATURE = 0xC
    COMMUNICATION_LOST = 0xD
    OVERLOAD = 0xE

    @property
    def is_fault(self) -> bool:
        return self not in (Status.DISABLED, Status.ENABLED)

    @property
    def fix(self) -> str:
        """What a user should do about this status."""
        return _FIXES.get(self, "")


_FIXES = {
    Status.OVER_VOLTAGE: "check the supply voltage (regenerated energy from fast braking also raises it)",
    Status.UNDER_VOLTAGE: "check the power supply and its cable; the supply may sag under load",
    Status.OVER_CURRENT: "the joint is blocked or the gains are too high: free the joint, lower kp/kd",
    Status.MOS_OVER_TEMPERATURE: "let the driver cool down and lower the load or duty cycle",
    Status.COIL_OVER_TEMPERATURE: "let the motor cool down and lower the load or duty cycle",
    Status.COMMUNICATION_LOST: "the motor's CAN timeout fired: check the bus and that commands reach it",
    Status.OVERLOAD: "the joint is overloaded: lower the load or the torque limit",
}


@dataclass(frozen=True)
class Feedback:
    """One decoded feedback frame: motor-side position (rad), velocity (rad/s), torque (N m), temperatures."""

    can_id_low: int
    status: Status
    q: float
    dq: float
    tau: float
    t_mos_c: int
    t_rotor_c: int


@dataclass(frozen=True)
class ParamReply:
    """A parameter register's value as read back from a motor."""

    can_id: int
    register: int
    value: float


class FrameError(ValueError):
    """A frame that is not what the protocol allows (wrong length, unknown status, wrong kind)."""


def _to_uint(x: float, lo: float, hi: float, bits: int, nearest: bool = False) -> int:
    """x clamped to [lo, hi], mapped linearly onto 0 .. 2^bits - 1, truncated (the Damiao reference's rule) or
    rounded to the nearest step. A non-finite x reads as 0 (every range holds 0: no position offset, velocity, gain
    or torque), never as a range end."""
    x = min(max(float(x), lo), hi) if math.isfinite(x) else 0.0  # a scalar clamp: np.clip is slow on scalars
    scaled = (x - lo) / (hi - lo) * ((1 << bits) - 1)
    return int(round(scaled)) if nearest else int(scaled)


def _to_float(u: int, lo: float, hi: float, bits: int) -> float:
    return u / ((1 << bits) - 1) * (hi - lo) + lo


def special(command: Special) -> bytes:
    """Enable / disable / set-zero / clear-error payload (sent on the motor's CAN id)."""
    return bytes([0xFF] * 7 + [int(command)])


def pack_mit(q: float, dq: float, kp: float, kd: float, tau: float, limits: MotorLimits) -> bytes:
    """MIT command payload; every value is clamped to its range. A non-finite value becomes 0 (kp = kd = 0: a
    limp motor, not a full-scale one); the driver refuses such commands before they get here."""
    qi = _to_uint(q, -limits.p_max, limits.p_max, 16)
    dqi = _to_uint(dq, -limits.v_max, limits.v_max, 12)
    kpi = _to_uint(kp, 0.0, KP_MAX, 12)
    kdi = _to_uint(kd, 0.0, KD_MAX, 12)
    ti = _to_uint(tau, -limits.t_max, limits.t_max, 12)
    return bytes([
        qi >> 8, qi & 0xFF, dqi >> 4, ((dqi & 0xF) << 4) | (kpi >> 8), kpi & 0xFF,
        kdi >> 4, ((kdi & 0xF) << 4) | (ti >> 8), ti & 0xFF,
    ])


def unpack_mit(data: bytes, limits: MotorLimits) -> tuple[float, float, float, float, float]:
    """(q, dq, kp, kd, tau) of an MIT command payload (the simulated motor's side)."""
    if len(data) != FRAME_LEN:
        raise FrameError(f"MIT command has {len(data)} bytes, expected {FRAME_LEN}")
    if is_special(data):
        raise FrameError("frame is a special command, not an MIT command")
    qi = data[0] << 8 | data[1]
    dqi = data[2] << 4 | data[3] >> 4
    kpi = (data[3] & 0xF) << 8 | data[4]
    kdi = data[5] << 4 | data[6] >> 4
    ti = (data[6] & 0xF) << 8 | data[7]
    return (_to_float(qi, -limits.p_max, limits.p_max, 16), _to_float(dqi, -limits.v_max, limits.v_max, 12),
            _to_float(kpi, 0.0, KP_MAX, 12), _to_float(kdi, 0.0, KD_MAX, 12),
            _to_float(ti, -limits.t_max, limits.t_max, 12))


def is_special(data: bytes) -> bool:
    """True for the FF x7 special commands. An MIT command at full scale in q, dq, kp and kd with tau near
    +TMAX would read the same, so the driver keeps commands inside the ranges (safety limits below PMAX)."""
    return len(data) == FRAME_LEN and data[:7] == b"\xff" * 7 and data[7] in {int(s) for s in Special}


def pack_feedback(can_id: int, status: Status, q: float, dq: float, tau: float, t_mos_c: int, t_rotor_c: int,
                  limits: MotorLimits) -> bytes:
    """Feedback payload as a motor sends it (the simulated motor's side, rounded to the nearest step)."""
    qi = _to_uint(q, -limits.p_max, limits.p_max, 16, nearest=True)
    dqi = _to_uint(dq, -limits.v_max, limits.v_max, 12, nearest=True)
    ti = _to_uint(tau, -limits.t_max, limits.t_max, 12, nearest=True)
    return bytes([
        (int(status) << 4) | (can_id & 0xF), qi >> 8, qi & 0xFF, dqi >> 4, ((dqi & 0xF) << 4) | (ti >> 8),
        ti & 0xFF, min(max(int(t_mos_c), 0), 255), min(max(int(t_rotor_c), 0), 255),
    ])


def unpack_feedback(data: bytes, limits: MotorLimits) -> Feedback:
    """Decode a feedback payload; FrameError if it is not 8 bytes, is a parameter reply or has an unknown status."""
    if len(data) != FRAME_LEN:
        raise FrameError(f"feedback frame has {len(data)} bytes, expected {FRAME_LEN}")
    try:
        status = Status(data[0] >> 4)
    except ValueError as exc:
        raise FrameError(f"feedback frame has unknown status 0x{data[0] >> 4:X}") from exc
    qi = data[1] << 8 | data[2]
    dqi = data[3] << 4 | data[4] >> 4
    ti = (data[4] & 0xF) << 8 | data[5]
    return Feedback(
        can_id_low=data[0] & 0xF, status=status,
        q=_to_float(qi, -limits.p_max, limits.p_max, 16), dq=_to_float(dqi, -limits.v_max, limits.v_max, 12),
        tau=_to_float(ti, -limits.t_max, limits.t_max, 12), t_mos_c=data[6], t_rotor_c=data[7],
    )


def param_read(can_id: int, register: int) -> bytes:
    """Parameter read request (sent on PARAM_ID)."""
    _check_id(can_id)
    return bytes([can_id & 0xFF, (can_id >> 8) & 0x07, PARAM_READ, register & 0xFF, 0, 0, 0, 0])


def param_write(can_id: int, register: int, value: float) -> bytes:
    """Parameter write request (sent on PARAM_ID); the motor answers with the value it now holds. The value lives
    in RAM until the motor stores its parameters (this driver never does: a power cycle restores them)."""
    _check_id(can_id)
    return bytes([can_id & 0xFF, (can_id >> 8) & 0x07, PARAM_WRITE, register & 0xFF]) + \
        param_value_bytes(register, value)


def timeout_steps(timeout_s: float) -> int:
    """The REG_TIMEOUT value of a communication timeout of `timeout_s` seconds (whole TIMEOUT_UNIT_S steps)."""
    return int(round(timeout_s / TIMEOUT_UNIT_S))


def refresh_request(can_id: int) -> bytes:
    """Ask a motor for one feedback frame without changing its state (sent on PARAM_ID)."""
    _check_id(can_id)
    return bytes([can_id & 0xFF, (can_id >> 8) & 0x07, REFRESH, 0, 0, 0, 0, 0])


def param_value_bytes(register: int, value: float) -> bytes:
    """A register value as the 4 little-endian bytes of a parameter frame."""
    if register in INTEGER_REGISTERS:
        return struct.pack("<I", int(value))
    return struct.pack("<f", float(value))


def pack_param_reply(can_id: int, register: int, value: float, operation: int = PARAM_READ) -> bytes:
    """Parameter reply payload to a read (or, with `operation` PARAM_WRITE, a write): the simulated motor's side."""
    return bytes([can_id & 0xFF, (can_id >> 8) & 0x07, operation, register]) + param_value_bytes(register, value)


def is_param_reply(data: bytes, can_id: int) -> bool:
    """True if `data` reads as motor `can_id`'s answer to a parameter read or write.

    Feedback and parameter replies share the master id; a feedback frame only looks like this when its
    position bytes happen to match, so the driver reads parameters while the motor is not streaming."""
    return (len(data) == FRAME_LEN and data[0] == can_id & 0xFF and data[1] == (can_id >> 8) & 0x07
            and data[2] in (PARAM_READ, PARAM_WRITE))


def unpack_param_reply(data: bytes) -> ParamReply:
    """Decode a parameter reply; FrameError if the frame is not one."""
    if len(data) != FRAME_LEN or data[2] not in (PARAM_READ, PARAM_WRITE):
        raise FrameError("frame is not a parameter reply (8 bytes, byte 2 = 0x33 or 0x55)")
    register = data[3]
    if register in INTEGER_REGISTERS:
        value = float(struct.unpack("<I", data[4:8])[0])
    else:
        value = float(struct.unpack("<f", data[4:8])[0])
    return ParamReply(data[0] | (data[1] & 0x07) << 8, register, value)


def unpack_param_request(data: bytes) -> tuple[int, int, int]:
    """(CAN id, operation 0x33 / 0x55 / 0xCC, register) of a request on PARAM_ID (the simulated motor's side)."""
    if len(data) < 4 or data[2] not in (PARAM_READ, PARAM_WRITE, REFRESH):
        raise FrameError("frame on 0x7FF is not a parameter read, write or refresh")
    return data[0] | (data[1] & 0x07) << 8, data[2], data[3]


def _check_id(can_id: int) -> None:
    if not 0 < can_id < PARAM_ID:
        raise ValueError(f"CAN id {can_id} is outside 1 .. 0x7FE")
