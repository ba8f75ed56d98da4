"""The CAN driver's motor layer on python-can's virtual bus: one request/reply loop (first accepted reply, retries,
no answer) under parameter reads, feedback requests and the scan; channel unit conversions."""

import itertools
import time

import can
import pytest

from drivers.arm.can_bus import CanBus
from drivers.arm.damiao import (
    MODELS,
    PARAM_ID,
    REG_MST_ID,
    REG_PMAX,
    REG_TIMEOUT,
    REG_TMAX,
    REG_VMAX,
    Status,
    pack_feedback,
    pack_param_reply,
    refresh_request,
    unpack_mit,
    unpack_param_request,
)
from drivers.arm.motor_channels import (
    PMAX_MARGIN,
    MotorChannel,
    check_feedback,
    read_param,
    request_feedback,
    request_reply,
    scan_bus,
)
from drivers.arm.robot_config import MotorConfig, WatchdogConfig
from drivers.errors import ArmError

J4310 = MODELS["DM4310"]
_channels = itertools.count()


class Peer:
    """The far end of a virtual channel: answers each request it has received with `answer(request, n)` (n counts
    requests from 1), a list of (arbitration id, payload). Runs as the CanBus pump, before every receive poll."""

    def __init__(self, answer):
        self.channel = f"test-can-motors-{next(_channels)}"
        self.bus = can.Bus(interface="virtual", channel=self.channel)
        self.answer = answer
        self.requests: list[can.Message] = []

    def pump(self) -> None:
        while (msg := self.bus.recv(0.0)) is not None:
            self.requests.append(msg)
            for arbitration_id, data in self.answer(msg, len(self.requests)):
                self.bus.send(can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False))


@pytest.fixture
def connect():
    opened = []

    def make(answer):
        peer = Peer(answer)
        bus = CanBus(peer.channel, "virtual", pump=peer.pump)
        opened.append((bus, peer))
        return bus, peer

    yield make
    for bus, peer in opened:
        bus.close()
        peer.bus.shutdown()


def _first_byte(msg: can.Message) -> int | None:
    """A reply parser accepting frames on id 0x11 whose first byte is not zero."""
    return msg.data[0] if msg.arbitration_id == 0x11 and msg.data[0] else None


def test_request_reply_returns_the_first_accepted_frame(connect):
    bus, peer = connect(lambda _msg, _n: [(0x12, b"\x07" * 8), (0x11, bytes(8)), (0x11, b"\x05" * 8),
                                          (0x11, b"\x06" * 8)])
    assert request_reply(bus, 0x01, b"\x01", _first_byte, 0.05) == 5
    assert len(peer.requests) == 1 and peer.requests[0].arbitration_id == 0x01


def test_request_reply_retries_an_unanswered_request(connect):
    bus, peer = connect(lambda _msg, n: [(0x11, b"\x09" * 8)] if n == 2 else [])
    assert request_reply(bus, 0x01, b"\x01", _first_byte, 0.01, attempts=3) == 9
    assert len(peer.requests) == 2


def test_request_reply_gives_none_after_every_attempt_timed_out(connect):
    bus, peer = connect(lambda _msg, _n: [(0x11, bytes(8))])  # answers, but never acceptably
    t0 = time.perf_counter()
    assert request_reply(bus, 0x01, b"\x01", _first_byte, 0.01, attempts=3) is None
    assert len(peer.requests) == 3 and time.perf_counter() - t0 >= 0.03


def _motor(can_id: int, master_id: int, registers: dict[int, float], feedback: bytes | None):
    """A motor answering parameter reads of `registers` and refresh requests with `feedback`."""

    def answer(msg: can.Message, _n: int) -> list[tuple[int, bytes]]:
        if msg.arbitration_id != PARAM_ID:
            return []
        target, op, register = unpack_param_request(bytes(msg.data))
        if target != can_id:
            return []
        if op == 0x33 and register in registers:
            return [(master_id, pack_param_reply(can_id, register, registers[register]))]
        return [(master_id, feedback)] if op == 0xCC and feedback is not None else []

    return answer


LIMIT_REGISTERS = {REG_MST_ID: 0x13, REG_PMAX: 12.5, REG_VMAX: 30.0, REG_TMAX: 10.0, REG_TIMEOUT: 2000}


def test_read_param_skips_other_registers_and_names_the_motor_when_silent(connect):
    bus, _ = connect(_motor(3, 0x13, LIMIT_REGISTERS, None))
    assert read_param(bus, 3, 0x13, REG_VMAX, 0.02, "joint3") == pytest.approx(30.0)
    with pytest.raises(ArmError, match=r"motor joint3 did not answer a parameter read \(register 24\) 3 times "
                                       r"within 5 ms: .*deploy arm scan"):
        read_param(bus, 3, 0x13, 24, 0.005, "joint3")


def test_request_feedback_counts_malformed_frames_then_fails():
    channel = MotorChannel("joint3", MotorConfig(can_id=3, master_id=0x13), J4310)
    good = pack_feedback(3, Status.ENABLED, 1.0, 0.5, 0.2, 30, 31, J4310)
    bad = bytes([0x71, *good[1:]])  # status 0x7 does not exist
    peer = Peer(lambda msg, n: [(0x13, bad), (0x13, good if n == 2 else bad)])
    bus = CanBus(peer.channel, "virtual", pump=peer.pump)
    try:
        request_feedback(bus, channel, refresh_request(3), PARAM_ID, 0.02, lambda: 4.0)
        assert channel.feedback.q == pytest.approx(1.0, abs=1e-3) and channel.t_feedback == 4.0
        assert channel.malformed == 3 and len(peer.requests) == 2
        peer.answer = lambda _msg, _n: [(0x13, bad)]
        with pytest.raises(ArmError, match=r"motor joint3 \(CAN id 3, master 0x13\) did not answer 3 times within "
                                           r"5 ms"):
            request_feedback(bus, channel, refresh_request(3), PARAM_ID, 0.005, lambda: 5.0)
    finally:
        bus.close()
        peer.bus.shutdown()


@pytest.mark.parametrize(("feedback", "status"), [
    (pack_feedback(3, Status.DISABLED, 0.0, 0.0, 0.0, 25, 25, J4310), "disabled"),
    (bytes(3), "malformed feedback"),
    (None, "no feedback"),
])
def test_scan_reports_ids_limits_and_the_feedback_status(connect, feedback, status):
    bus, _ = connect(_motor(3, 0x13, LIMIT_REGISTERS, feedback))
    found = scan_bus(bus, range(1, 5), timeout_s=0.005)
    assert [m.to_dict() for m in found] == [
        {"can_id": 3, "master_id": 0x13, "status": status, "p_max": 12.5, "v_max": 30.0, "t_max": 10.0,
         "timeout_ms": 100.0, "fd": False}]


def test_channel_converts_between_joint_and_motor_side():
    c = MotorChannel("j", MotorConfig(can_id=1, master_id=0x11, direction=-1, zero_offset=0.5), J4310)
    q_m, dq_m, kp, kd, tau_m = unpack_mit(c.mit_frame(0.8, 1.0, 30.0, 1.0, 2.0), J4310)
    assert q_m == pytest.approx(-0.3, abs=1e-3) and dq_m == pytest.approx(-1.0, abs=0.02)
    assert tau_m == pytest.approx(-2.0, abs=0.01) and kp == pytest.approx(30.0, abs=0.2)
    assert c.to_joint(q_m, "q") == pytest.approx(0.8, abs=1e-3) and c.to_joint(dq_m, "dq") == pytest.approx(1.0, 0.02)
    far, *_ = unpack_mit(c.mit_frame(-100.0, 0.0, 0.0, 0.0), J4310)  # clamped inside PMAX: never a special frame
    assert far == pytest.approx(PMAX_MARGIN * J4310.p_max, abs=1e-3)
    assert c.report()["status"] == "no feedback" and c.report()["q"] is None


def test_stale_feedback_and_too_much_torque_are_faults():
    c = MotorChannel("j", MotorConfig(can_id=1, master_id=0x11), J4310)
    c.feedback = c.decode(pack_feedback(1, Status.ENABLED, 0.0, 0.0, 6.0, 25, 25, J4310))
    watchdog = WatchdogConfig()
    check_feedback(c, 0.0, watchdog, tau_max=6.0)
    check_feedback(c, 0.0, watchdog, tau_max=None)  # the gripper: no torque check
    with pytest.raises(ArmError, match=r"safety stop: joint j .*torque 6.0 N m exceeds 4.8 N m"):
        check_feedback(c, 0.0, watchdog, tau_max=4.0)
    with pytest.raises(ArmError, match=r"watchdog: joint j .*no valid feedback for 30 ms \(limit 20 ms"):
        check_feedback(c, 0.03, watchdog, tau_max=6.0)
