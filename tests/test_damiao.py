"""Damiao MIT protocol: bit layout, round trips and clamping (hypothesis), malformed frames rejected."""

import struct

import pytest
from hypothesis import given
from hypothesis import strategies as st

from drivers.arm.damiao import (
    KD_MAX,
    KP_MAX,
    MODELS,
    REG_PMAX,
    REG_TMAX,
    FrameError,
    MotorLimits,
    Special,
    Status,
    is_param_reply,
    is_special,
    pack_feedback,
    pack_mit,
    pack_param_reply,
    param_read,
    special,
    unpack_feedback,
    unpack_mit,
    unpack_param_reply,
    unpack_param_request,
)

J4310 = MODELS["DM4310"]
limits_st = st.builds(MotorLimits, st.floats(0.5, 50), st.floats(0.5, 300), st.floats(0.2, 300))
wide = st.floats(-1e6, 1e6, allow_nan=False)


def test_mit_bit_layout_matches_the_datasheet():
    # q = +PMAX -> 0xFFFF; dq = -VMAX -> 0; kp = 500 -> 0xFFF; kd = 0 -> 0; tau = 0 -> 0x7FF (2047.5 truncated)
    data = pack_mit(12.5, -30.0, 500.0, 0.0, 0.0, J4310)
    assert data == bytes([0xFF, 0xFF, 0x00, 0x0F, 0xFF, 0x00, 0x07, 0xFF])
    # kd = 5 -> 0xFFF split over D5 (high 8 bits) and D6's high nibble; tau = -TMAX -> 0
    data = pack_mit(-12.5, 30.0, 0.0, 5.0, -10.0, J4310)
    assert data == bytes([0x00, 0x00, 0xFF, 0xF0, 0x00, 0xFF, 0xF0, 0x00])


def test_special_commands():
    assert special(Special.ENABLE) == bytes([0xFF] * 7 + [0xFC])
    assert special(Special.DISABLE)[-1] == 0xFD and special(Special.SET_ZERO)[-1] == 0xFE
    assert special(Special.CLEAR_ERROR)[-1] == 0xFB
    assert all(is_special(special(s)) for s in Special)
    assert not is_special(pack_mit(0, 0, 10, 1, 0, J4310))
    with pytest.raises(FrameError):
        unpack_mit(special(Special.ENABLE), J4310)


@given(limits_st, st.floats(-1, 1), st.floats(-1, 1), st.floats(0, 1), st.floats(0, 1), st.floats(-1, 1))
def test_mit_round_trip_within_one_quantum(lim, fq, fdq, fkp, fkd, ftau):
    q, dq, kp, kd, tau = fq * lim.p_max, fdq * lim.v_max, fkp * KP_MAX, fkd * KD_MAX, ftau * lim.t_max
    out = unpack_mit(pack_mit(q, dq, kp, kd, tau, lim), lim)
    quanta = (2 * lim.p_max / 65535, 2 * lim.v_max / 4095, KP_MAX / 4095, KD_MAX / 4095, 2 * lim.t_max / 4095)
    for got, want, quantum in zip(out, (q, dq, kp, kd, tau), quanta, strict=True):
        assert -quantum - 1e-9 <= got - want <= 1e-9  # truncated, as the Damiao reference: at most a step below


@given(limits_st, wide, wide, wide, wide, wide)
def test_mit_clamps_to_the_ranges(lim, q, dq, kp, kd, tau):
    out = unpack_mit(pack_mit(q, dq, kp, kd, tau, lim), lim)
    bounds = ((-lim.p_max, lim.p_max), (-lim.v_max, lim.v_max), (0, KP_MAX), (0, KD_MAX), (-lim.t_max, lim.t_max))
    for got, want, (lo, hi) in zip(out, (q, dq, kp, kd, tau), bounds, strict=True):
        assert lo - 1e-9 <= got <= hi + 1e-9
        if want >= hi:
            assert got == pytest.approx(hi)
        if want <= lo:
            assert got == pytest.approx(lo)


def test_non_finite_command_values_do_not_crash():
    data = pack_mit(float("nan"), float("inf"), float("nan"), 1.0, float("-inf"), J4310)
    # each non-finite value reads as 0 (q 0x7FFF, dq 0x7FF, kp 0x000, tau 0x7FF: truncated); kd = 1 -> 0x333
    assert data.hex(" ") == "7f ff 7f f0 00 33 37 ff"


@given(limits_st, st.integers(1, 0x7FE), st.sampled_from(list(Status)), st.floats(-1, 1), st.floats(-1, 1),
       st.floats(-1, 1), st.integers(0, 255), st.integers(0, 255))
def test_feedback_round_trip(lim, can_id, status, fq, fdq, ftau, t_mos, t_rotor):
    q, dq, tau = fq * lim.p_max, fdq * lim.v_max, ftau * lim.t_max
    fb = unpack_feedback(pack_feedback(can_id, status, q, dq, tau, t_mos, t_rotor, lim), lim)
    assert fb.status == status and fb.can_id_low == can_id & 0xF
    assert (fb.t_mos_c, fb.t_rotor_c) == (t_mos, t_rotor)
    assert abs(fb.q - q) <= lim.p_max / 65535 + 1e-9
    assert abs(fb.dq - dq) <= lim.v_max / 4095 + 1e-9 and abs(fb.tau - tau) <= lim.t_max / 4095 + 1e-9


def test_feedback_layout():
    # status 0xA (over-current) in D0's high nibble, id 3 in its low nibble; q = 0 -> 0x8000 (rounded 32767.5)
    data = pack_feedback(3, Status.OVER_CURRENT, 0.0, 0.0, 0.0, 40, 45, J4310)
    assert data[0] == 0xA3 and data[6:] == bytes([40, 45])
    fb = unpack_feedback(data, J4310)
    assert fb.status.is_fault and "blocked" in fb.status.fix
    assert not Status.ENABLED.is_fault and not Status.DISABLED.is_fault


@given(st.binary(max_size=16))
def test_malformed_feedback_raises_frame_error_only(data):
    try:
        fb = unpack_feedback(data, J4310)
    except FrameError:
        return
    assert len(data) == 8 and fb.status in Status


def test_unknown_status_and_short_frames_are_rejected():
    with pytest.raises(FrameError, match="unknown status"):
        unpack_feedback(bytes([0x21, 0, 0, 0, 0, 0, 0, 0]), J4310)
    with pytest.raises(FrameError, match="7 bytes"):
        unpack_feedback(bytes(7), J4310)
    with pytest.raises(FrameError):
        unpack_mit(bytes(9), J4310)


@given(st.integers(1, 0x7FE), st.sampled_from([REG_PMAX, 22, REG_TMAX, 7]), st.floats(0.125, 1000, width=32))
def test_parameter_read_and_reply(can_id, register, value):
    request = param_read(can_id, register)
    assert request[2] == 0x33 and unpack_param_request(request) == (can_id, 0x33, register)
    reply = pack_param_reply(can_id, register, value)
    assert is_param_reply(reply, can_id) and not is_param_reply(reply, can_id + 1 if can_id < 0x7FE else 1)
    parsed = unpack_param_reply(reply)
    assert (parsed.can_id, parsed.register) == (can_id, register)
    expected = float(int(value)) if register == 7 else value
    assert parsed.value == pytest.approx(expected, rel=1e-6)


def test_parameter_reply_is_little_endian_float():
    reply = pack_param_reply(1, REG_TMAX, 10.0)
    assert reply[:4] == bytes([1, 0, 0x33, REG_TMAX]) and struct.unpack("<f", reply[4:])[0] == 10.0
    with pytest.raises(FrameError):
        unpack_param_reply(bytes([1, 0, 0x12, 23, 0, 0, 0, 0]))
    with pytest.raises(ValueError):
        param_read(0x7FF, REG_PMAX)


def test_motor_limits_must_be_positive():
    with pytest.raises(ValueError):
        MotorLimits(12.5, 0.0, 10.0)
    with pytest.raises(ValueError):
        MotorLimits(float("nan"), 30.0, 10.0)
