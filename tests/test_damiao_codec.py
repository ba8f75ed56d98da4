"""The Damiao codec on values it must not pass through as they are: non-finite values become 0 (kp = kd = 0: a limp
motor), out-of-range values their range's end, each checked byte for byte; and the driver refusing to encode or
send a non-finite command at all (CanArm on simulated motors, every frame on the virtual bus read back)."""

import can
import pytest

from drivers.arm.damiao import MODELS, Special, Status, is_special, pack_feedback, pack_mit, special, unpack_mit
from drivers.arm.motor_channels import MotorChannel, gripper_frame
from drivers.arm.robot_config import MotorConfig, load_robot_config
from drivers.arm.safety import SafetyGuard
from drivers.errors import ArmError
from sim_fallback.devices import sim_can_arm

J4310 = MODELS["DM4310"]
P, V, T = J4310.p_max, J4310.v_max, J4310.t_max
FULL_SCALE = (P, -V, 500.0, 5.0, T)  # q 0xFFFF, dq 0x000, kp 0xFFF, kd 0xFFF, tau 0xFFF: every field's code known
FIELDS = ("q", "dq", "kp", "kd", "tau")
NON_FINITE = [float("nan"), float("inf"), float("-inf")]
PANDA = load_robot_config("panda_sim").model_copy(update={"control_rate_hz": 500.0})


def _hex(data: bytes) -> str:
    return data.hex(" ")


@pytest.mark.parametrize("value", NON_FINITE)
def test_a_non_finite_command_encodes_as_zero_in_every_field(value):
    # q = 0 -> 0x7FFF and dq = tau = 0 -> 0x7FF (32767.5 and 2047.5 truncated); kp = kd = 0 -> 0x000
    assert _hex(pack_mit(value, value, value, value, value, J4310)) == "7f ff 7f f0 00 00 07 ff"


@pytest.mark.parametrize("value", NON_FINITE)
@pytest.mark.parametrize(("field", "expected"), [
    ("q", "7f ff 00 0f ff ff ff ff"),  # q 0x7FFF between full-scale others
    ("dq", "ff ff 7f ff ff ff ff ff"),  # dq 0x7FF
    ("kp", "ff ff 00 00 00 ff ff ff"),  # kp 0x000 (not its range's centre 0x800: a stiff gain toward nowhere)
    ("kd", "ff ff 00 0f ff 00 0f ff"),  # kd 0x000
    ("tau", "ff ff 00 0f ff ff f7 ff"),  # tau 0x7FF
])
def test_each_non_finite_field_alone_becomes_zero(field, expected, value):
    assert _hex(pack_mit(*FULL_SCALE, J4310)) == "ff ff 00 0f ff ff ff ff"
    values = list(FULL_SCALE)
    values[FIELDS.index(field)] = value
    assert _hex(pack_mit(*values, J4310)) == expected


@pytest.mark.parametrize("beyond", [1e-9, 1.0, 1e6])
def test_out_of_range_values_encode_as_their_range_ends(beyond):
    above = pack_mit(P + beyond, V + beyond, 500.0 + beyond, 5.0 + beyond, T + beyond, J4310)
    assert _hex(above) == "ff ff ff ff ff ff ff ff" and not is_special(above)
    assert _hex(pack_mit(-P - beyond, -V - beyond, -beyond, -beyond, -T - beyond, J4310)) == "00 00 00 00 00 00 00 00"


@pytest.mark.parametrize("field", FIELDS)
@pytest.mark.parametrize("side", ["above", "below"])
def test_each_field_clamps_to_its_own_range_end(field, side):
    """One field beyond its range reads back as that end; the others are untouched."""
    i = FIELDS.index(field)
    lo, hi = [(-P, P), (-V, V), (0.0, 500.0), (0.0, 5.0), (-T, T)][i]
    inside = [0.5 * P, 0.25 * V, 30.0, 1.0, -0.5 * T]
    beyond, end = list(inside), list(inside)
    beyond[i], end[i] = (hi + 3.0, hi) if side == "above" else (lo - 3.0, lo)
    assert pack_mit(*beyond, J4310) == pack_mit(*end, J4310)
    got = unpack_mit(pack_mit(*beyond, J4310), J4310)
    assert got[i] == pytest.approx(end[i], abs=1e-12)
    assert pack_mit(*inside, J4310) != pack_mit(*end, J4310)


def test_feedback_with_non_finite_values_and_out_of_range_temperatures():
    data = pack_feedback(1, Status.ENABLED, float("nan"), float("inf"), float("-inf"), 25, 30, J4310)
    assert _hex(data) == "11 80 00 80 08 00 19 1e"
    assert _hex(pack_feedback(2, Status.OVERLOAD, 1e6, -1e6, 1e6, -5, 300, J4310)) == "e2 ff ff 00 0f ff 00 ff"


# --- the driver refuses non-finite commands ---------------------------------------------------------------------


@pytest.mark.parametrize("value", NON_FINITE)
@pytest.mark.parametrize("field", FIELDS)
def test_a_motor_channel_refuses_to_encode_a_non_finite_command(field, value):
    c = MotorChannel("panda_joint3", MotorConfig(can_id=3, master_id=0x13), J4310)
    values = dict(zip(FIELDS, [0.1, 0.0, 30.0, 1.0, 0.5], strict=True))
    values[field] = value
    with pytest.raises(ArmError, match=r"^motor panda_joint3 \(CAN id 3, master 0x13\): MIT command .* is not finite"):
        c.mit_frame(**values)


def test_a_gripper_command_of_non_finite_width_is_refused_by_its_channel():
    g = PANDA.gripper
    c = MotorChannel("gripper", g, g.default_limits)
    with pytest.raises(ArmError, match="is not finite"):
        gripper_frame(c, g, float("nan"), 40.0)


class _Bus:
    """Every frame on the arm's virtual CAN channel, read by a second endpoint (python-can's virtual bus)."""

    def __init__(self, channel: str) -> None:
        self.bus = can.Bus(interface="virtual", channel=channel)

    def commands(self) -> list[can.Message]:
        """The frames sent to motors (CAN ids 1..8) since the last call."""
        out = []
        while (msg := self.bus.recv(0.0)) is not None:
            if 1 <= msg.arbitration_id <= 8:
                out.append(msg)
        return out


def _mit_commands(frames: list[can.Message]) -> list[tuple[int, tuple]]:
    return [(m.arbitration_id, unpack_mit(bytes(m.data), MODELS["DM10010L" if m.arbitration_id <= 4 else "DM4340"]))
            for m in frames if m.arbitration_id <= 7 and not is_special(bytes(m.data))]


def _disables(frames: list[can.Message]) -> dict[int, int]:
    out: dict[int, int] = {}
    for m in frames:
        if bytes(m.data) == special(Special.DISABLE):
            out[m.arbitration_id] = out.get(m.arbitration_id, 0) + 1
    return out


@pytest.mark.parametrize("value", NON_FINITE)
def test_the_can_arm_never_sends_a_non_finite_command(value):
    arm, motors = sim_can_arm(PANDA)
    with arm:
        bus = _Bus(arm.config.can.channel)
        for _ in range(3):
            arm.sync()
        assert len(_mit_commands(bus.commands())) == 3 * 7
        q_hold = arm.state().q
        q = q_hold.copy()
        q[2] = value
        with pytest.raises(ArmError, match="^safety stop: joint panda_joint3 position command is not finite"):
            arm.command(q)
        frames = bus.commands()
        sent = _mit_commands(frames)
        assert sent, "the stop damps before it disables"
        for can_id, (q_m, dq_m, kp, _, _) in sent:  # only the stop's damping: kp = 0 at the held position
            assert kp == 0.0 and abs(q_m - q_hold[can_id - 1]) < 1e-3 and dq_m == pytest.approx(0.0, abs=0.01)
        assert set(_disables(frames)) == set(range(1, 9))
        assert not any(m.enabled for m in motors.motors)


class _BrokenGuard(SafetyGuard):
    """A safety layer with a bug that lets everything through: the motor channel is the last line."""

    def check(self, *args, **kwargs) -> None:
        return None


def test_a_non_finite_command_past_a_broken_guard_trips_the_loop_before_any_frame():
    arm, motors = sim_can_arm(PANDA)
    arm.guard = _BrokenGuard(arm.limits, arm.joint_names)
    with arm:
        bus = _Bus(arm.config.can.channel)
        arm.sync()
        bus.commands()
        q = arm.state().q
        q[2] = float("nan")
        arm.command(q)  # the broken guard accepts it
        with pytest.raises(ArmError, match=r"^motor panda_joint3 .*MIT command \(q nan.* is not finite"):
            arm.sync()
        frames = bus.commands()
        assert _mit_commands(frames) == []  # not one frame of that cycle left: they are all built before sending
        assert set(_disables(frames)) == set(range(1, 9))
        assert not any(m.enabled for m in motors.motors)
        with pytest.raises(ArmError, match="is not finite"):  # the fault stays until a new connect
            arm.command(arm.state().q)
