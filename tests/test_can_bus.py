"""CanBus on python-can's virtual interface: frames, error frames (bus-off, error-passive), send failures."""

import errno

import can
import pytest

from drivers.arm.can_bus import (
    CAN_ERR_BUSOFF,
    CAN_ERR_CRTL,
    CAN_ERR_CRTL_RX_PASSIVE,
    CanBus,
    classify_send_error,
    fix_bus_off,
)
from drivers.errors import ArmError, CanBusError


@pytest.fixture
def pair():
    bus = CanBus("test-can-bus", "virtual")
    peer = can.Bus(interface="virtual", channel="test-can-bus")
    yield bus, peer
    bus.close()
    peer.shutdown()


def test_frames_go_both_ways(pair):
    bus, peer = pair
    bus.send(0x01, bytes(range(8)))
    msg = peer.recv(0.5)
    assert msg.arbitration_id == 0x01 and bytes(msg.data) == bytes(range(8)) and not msg.is_extended_id
    peer.send(can.Message(arbitration_id=0x11, data=b"\x10" * 8, is_extended_id=False))
    assert bytes(bus.recv(0.5).data) == b"\x10" * 8
    assert bus.recv(0.01) is None
    bus.check_state()  # the virtual bus reports error-active


def test_bus_off_error_frame(pair):
    bus, peer = pair
    peer.send(can.Message(arbitration_id=CAN_ERR_BUSOFF, is_error_frame=True, data=bytes(8), is_extended_id=False))
    with pytest.raises(CanBusError, match="bus-off.*120 ohm.*restart-ms"):
        bus.recv(0.5)


def test_error_passive_error_frame(pair):
    bus, peer = pair
    data = bytes([0, CAN_ERR_CRTL_RX_PASSIVE, 0, 0, 0, 0, 0, 0])
    peer.send(can.Message(arbitration_id=CAN_ERR_CRTL, is_error_frame=True, data=data, is_extended_id=False))
    with pytest.raises(CanBusError, match="error-passive.*bitrate"):
        bus.recv(0.5)


def test_no_buffer_space_is_named_with_the_fix():
    exc = can.CanOperationError("Failed to transmit: [Errno 105] No buffer space available", error_code=errno.ENOBUFS)
    err = classify_send_error(exc, "can0", 0x03, fix_bus_off("can0", 1_000_000, False, 5_000_000))
    assert isinstance(err, CanBusError) and isinstance(err, ArmError)
    assert "No buffer space" in str(err) and "txqueuelen" in str(err) and "0x3" in str(err)
    other = classify_send_error(can.CanOperationError("Network is down"), "can0", 0x03,
                                fix_bus_off("can0", 1_000_000, False, 5_000_000))
    assert "Network is down" in str(other) and "ip link" in str(other)


def test_the_bus_off_fix_restarts_the_link_as_configured():
    """An OpenArm's CAN FD link is restarted with its data bitrate and FD on; a classic link without them."""
    fd = fix_bus_off("can1", 1_000_000, True, 5_000_000)
    assert "ip link set can1 up type can bitrate 1000000 dbitrate 5000000 fd on restart-ms 100" in fd
    classic = fix_bus_off("can0", 500_000, False, 5_000_000)
    assert "type can bitrate 500000 restart-ms 100" in classic and "fd on" not in classic


def test_unknown_interface_is_one_clear_error():
    with pytest.raises(CanBusError, match="cannot be opened.*ip link show"):
        CanBus("can0", "no-such-interface")


def test_send_after_close_is_a_bus_error():
    bus = CanBus("test-closed", "virtual")
    bus.close()
    bus.close()
    with pytest.raises(CanBusError):
        bus.send(0x01, bytes(8))
