"""A python-can bus for the arm: send and receive raw frames, turn bus trouble into one clear ArmError.

Detected: bus-off and error-passive (SocketCAN error frames, and `bus.state` where the interface reports it),
a full transmit queue ("No buffer space available", ENOBUFS), and any other send or receive failure.
"""

from __future__ import annotations

import errno
import logging
import time
from collections.abc import Callable
from typing import TYPE_CHECKING

import can

from drivers.errors import CanBusError
from drivers.interrupts import critical

if TYPE_CHECKING:
    from drivers.arm.robot_config import CanConfig

# SocketCAN error frame classes (linux/can/error.h): bits of the error frame's id, details in data[1]
CAN_ERR_CRTL, CAN_ERR_BUSOFF, CAN_ERR_RESTARTED = 0x004, 0x040, 0x100
CAN_ERR_CRTL_RX_PASSIVE, CAN_ERR_CRTL_TX_PASSIVE = 0x10, 0x20

FIX_PASSIVE = "too many bus errors: check the bitrate matches the motors, the wiring and the terminations"
# the pip package an interface of python-can needs (its extra); the others need their vendor's driver
INTERFACE_PACKAGES = {"damiao": "python-can-damiao", "slcan": "pyserial", "serial": "pyserial", "robotell": "pyserial",
                      "seeedstudio": "pyserial",
                      "gs_usb": "gs-usb", "cantact": "cantact", "canalystii": "canalystii", "neovi": "python-ics",
                      "nixnet": "nixnet", "udp_multicast": "msgpack"}
FIX_NOBUFS = ("the transmit queue is full (frames are not acknowledged): check that the motors are powered and "
              "wired, or raise the queue (`sudo ip link set can0 txqueuelen 1000`)")


class CanBus:
    """One CAN channel (python-can). `pump` (simulation only) runs before every receive poll so that a
    simulated motor bus without its own thread can answer."""

    def __init__(
        self,
        channel: str,
        interface: str = "socketcan",
        bitrate: int = 1_000_000,
        fd: bool = False,
        data_bitrate: int = 5_000_000,
        pump: Callable[[], None] | None = None,
    ) -> None:
        self.channel, self.interface, self.fd = channel, interface, fd
        self.fix_bus_off = fix_bus_off(channel, bitrate, fd, data_bitrate)
        self.pump = pump
        kwargs: dict = {"interface": interface, "channel": channel}
        if interface not in ("virtual", "socketcan"):  # socketcan's bitrate is set with `ip link`
            kwargs["bitrate"] = bitrate
        if fd and interface == "virtual":  # python-can's in-process bus carries FD frames once told its protocol
            kwargs["protocol"] = can.CanProtocol.CAN_FD
        elif fd:
            kwargs.update(fd=True, data_bitrate=data_bitrate)
        can_log = logging.getLogger("can")
        level = can_log.level
        can_log.setLevel(logging.ERROR)  # python-can warns of a missing library on its own line: the error says it
        try:
            self._bus = can.Bus(**kwargs)
        except (can.CanError, OSError, ValueError, ImportError) as exc:
            known = interface in can.interfaces.VALID_INTERFACES or interface in INTERFACE_PACKAGES
            if isinstance(exc, can.CanInterfaceNotImplementedError) and known:
                raise missing_driver_error(exc, interface) from exc
            raise CanBusError(
                f"CAN interface {interface!r} channel {channel!r} cannot be opened ({exc}): check the adapter is "
                f"plugged in and up (`ip link show {channel}`), or pick the interface in the robot config"
            ) from exc
        finally:
            can_log.setLevel(level)
        self._closed = False

    @classmethod
    def from_config(cls, can_config: CanConfig, pump: Callable[[], None] | None = None) -> CanBus:
        """The bus a robot config's [can] section names."""
        c = can_config
        return cls(c.channel, c.interface, c.bitrate, c.fd, c.data_bitrate, pump=pump)

    def send(self, arbitration_id: int, data: bytes) -> None:
        """Send one standard-id frame (CAN FD with bitrate switch on an FD bus); CanBusError naming the cause when
        the bus refuses it."""
        msg = can.Message(arbitration_id=arbitration_id, data=data, is_extended_id=False, is_fd=self.fd,
                          bitrate_switch=self.fd)
        try:
            with critical:  # python-can's virtual bus holds queue locks: a signal waits for the send's end
                self._bus.send(msg, timeout=0.001)
        except (can.CanError, OSError) as exc:
            raise classify_send_error(exc, self.channel, arbitration_id, self.fix_bus_off) from exc

    def recv(self, timeout: float) -> can.Message | None:
        """The next data frame within `timeout` s (None if none); CanBusError on an error frame or a dead bus."""
        deadline = time.perf_counter() + timeout
        while True:
            remaining = max(0.0, deadline - time.perf_counter())
            try:
                with critical:  # queue locks (virtual bus, simulated motors): a signal waits for the receive's end
                    if self.pump is not None:
                        self.pump()
                    msg = self._bus.recv(0.0 if self.pump is not None else remaining)
            except (can.CanError, OSError) as exc:
                raise CanBusError(f"CAN {self.channel}: receive failed ({exc}): {self.fix_bus_off}") from exc
            if msg is not None and msg.is_error_frame:
                self._raise_error_frame(msg)
            elif msg is not None:
                return msg
            if remaining <= 0.0:
                return None
            if self.pump is not None:
                time.sleep(min(remaining, 1e-4))

    def flush(self) -> None:
        """Let a pumped (simulated) bus handle what was sent; nothing to do on a real bus."""
        if self.pump is not None and not self._closed:
            self.pump()

    def check_state(self) -> None:
        """CanBusError if the interface reports error-passive or bus-off (interfaces that cannot tell say active)."""
        try:
            state = self._bus.state
        except (NotImplementedError, can.CanError, OSError):
            return
        if state == can.BusState.ERROR:
            raise CanBusError(f"CAN {self.channel} is bus-off: {self.fix_bus_off}")
        if state == can.BusState.PASSIVE:
            raise CanBusError(f"CAN {self.channel} is error-passive: {FIX_PASSIVE}")

    def _raise_error_frame(self, msg: can.Message) -> None:
        cls = msg.arbitration_id
        detail = msg.data[1] if len(msg.data) > 1 else 0
        if cls & CAN_ERR_BUSOFF:
            raise CanBusError(f"CAN {self.channel} went bus-off (error frame): {self.fix_bus_off}")
        if cls & CAN_ERR_CRTL and detail & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE):
            raise CanBusError(f"CAN {self.channel} controller is error-passive (error frame): {FIX_PASSIVE}")
        if cls & CAN_ERR_RESTARTED:
            return
        raise CanBusError(f"CAN {self.channel} reported bus errors (error class 0x{cls:03X}): {FIX_PASSIVE}")

    def close(self) -> None:
        """Release the interface (idempotent)."""
        if not self._closed:
            self._closed = True
            self._bus.shutdown()

    def __enter__(self) -> CanBus:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def missing_driver_error(exc: Exception, interface: str) -> CanBusError:
    """The CanBusError for an interface python-can knows but cannot use here: the library or driver to install."""
    package = INTERFACE_PACKAGES.get(interface)
    fix = (f"install {package} in the environment that runs deploy (`pip install {package}`)" if package else
           f"install the driver of your {interface} adapter from its vendor (python-can's documentation of the "
           f"{interface!r} interface names it)")
    return CanBusError(f"CAN interface {interface!r} cannot be used: the library or driver it needs is missing "
                       f"({exc}): {fix}")


def fix_bus_off(channel: str, bitrate: int, fd: bool, data_bitrate: int) -> str:
    """What to do after a bus-off on `channel`: the checks, and the `ip link` line that restarts it as configured
    (classic CAN or CAN FD at its bitrates)."""
    link = f"type can bitrate {bitrate}" + (f" dbitrate {data_bitrate} fd on" if fd else "")
    return ("check the CAN wiring, both 120 ohm terminations and the motor power, then restart the interface "
            f"(`sudo ip link set {channel} down && sudo ip link set {channel} up {link} restart-ms 100`)")


def classify_send_error(exc: Exception, channel: str, arbitration_id: int, fix: str) -> CanBusError:
    """The CanBusError for a failed send: a full transmit queue (ENOBUFS) or anything else (`fix`: what to do after a
    bus-off)."""
    code = getattr(exc, "error_code", None) or getattr(exc, "errno", None)
    if code == errno.ENOBUFS or "No buffer space" in str(exc):
        return CanBusError(f"CAN {channel}: No buffer space available sending to 0x{arbitration_id:X}: {FIX_NOBUFS}")
    return CanBusError(f"CAN {channel}: sending to 0x{arbitration_id:X} failed ({exc}): {fix}")
