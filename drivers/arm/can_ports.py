"""The CAN interfaces and adapters on this machine (`deploy arm find-port`), as lerobot-find-port lists serial ports:

- SocketCAN links (`ip -details -json link`): name, kind (can, vcan), whether up, controller state (ERROR-ACTIVE,
  BUS-OFF, ...), bitrate, data bitrate and CAN FD;
- serial adapters (/dev/ttyACM*, /dev/ttyUSB*) with their USB ids from sysfs, and the python-can interface that
  drives the known ones (Damiao's USB-CAN dongle: `damiao`, from the python-can-damiao plug-in);
- what python-can's `detect_available_configs` finds (its interfaces and installed plug-ins; the in-process
  software buses left out).
"""

from __future__ import annotations

import json
import logging
import shutil
import subprocess
from pathlib import Path

# USB vendor:product ids of CAN adapters -> (what it is, the python-can interface that drives it)
KNOWN_ADAPTERS = {
    (0x2E88, 0x4603): ("Damiao USB-CAN", "damiao"),
    (0x1D50, 0x606F): ("candleLight / CANable (gs_usb firmware)", "gs_usb"),
    (0xAD50, 0x60C4): ("CANable (slcan firmware)", "slcan"),
    (0x16D0, 0x117E): ("CANable (slcan firmware)", "slcan"),
    (0x0483, 0x1234): ("8devices USB2CAN", "usb2can"),
}
SOFTWARE_BUSES = ("virtual", "udp_multicast")  # python-can's own buses: not adapters


def socketcan_links(ip_links: list[dict] | None = None) -> list[dict]:
    """The CAN links among `ip_links` (`ip -details -json link`'s entries; default: this machine's)."""
    links = []
    for entry in _ip_links() if ip_links is None else ip_links:
        info = entry.get("linkinfo", {})
        kind = info.get("info_kind")
        if entry.get("link_type") != "can" and kind not in ("can", "vcan"):
            continue
        data = info.get("info_data", {})
        links.append({
            "name": entry.get("ifname"), "kind": kind or "can", "up": "UP" in entry.get("flags", []),
            "state": data.get("state", entry.get("operstate")),
            "bitrate": data.get("bittiming", {}).get("bitrate"),
            "data_bitrate": data.get("data_bittiming", {}).get("bitrate"),
            "fd": "FD" in data.get("ctrlmode", []) or entry.get("mtu") == 72,
        })
    return links


def _ip_links() -> list[dict]:
    """`ip -details -json link` of this machine ([] without iproute2)."""
    ip = shutil.which("ip")
    if ip is None:
        return []
    done = subprocess.run([ip, "-details", "-json", "link"], capture_output=True, text=True, timeout=5, check=False)
    return json.loads(done.stdout or "[]") if done.returncode == 0 else []


def serial_adapters(dev: Path = Path("/dev"), sys_tty: Path = Path("/sys/class/tty")) -> list[dict]:
    """/dev/ttyACM* and /dev/ttyUSB* with their USB vendor and product ids, names, and the python-can interface of a
    known CAN adapter (None: not one we know)."""
    found = []
    for device in sorted([*dev.glob("ttyACM*"), *dev.glob("ttyUSB*")]):
        usb = _usb_device(sys_tty / device.name / "device")
        vid, pid = (int(_read(usb / k) or "0", 16) for k in ("idVendor", "idProduct")) if usb else (0, 0)
        what, interface = KNOWN_ADAPTERS.get((vid, pid), (None, None))
        found.append({"device": str(device), "usb_id": f"{vid:04x}:{pid:04x}" if usb else None,
                      "manufacturer": _read(usb / "manufacturer") if usb else None,
                      "product": _read(usb / "product") if usb else None, "adapter": what, "interface": interface})
    return found


def _usb_device(path: Path) -> Path | None:
    """The USB device directory above a tty's sysfs device (the one holding idVendor), if any."""
    path = path.resolve() if path.exists() else None
    while path is not None and path != path.parent:
        if (path / "idVendor").is_file():
            return path
        path = path.parent
    return None


def _read(path: Path) -> str | None:
    try:
        return path.read_text().strip()
    except OSError:
        return None


def python_can_configs(timeout_s: float = 5.0) -> list[dict]:
    """What python-can's `detect_available_configs` finds, its software buses left out (its interfaces' missing
    libraries are not errors here: it logs them, this silences them)."""
    import can

    logging.disable(logging.CRITICAL)  # its interfaces log their missing libraries as they are tried
    try:
        configs = can.detect_available_configs(timeout=timeout_s)
    finally:
        logging.disable(logging.NOTSET)
    return [{k: v for k, v in c.items() if isinstance(v, str | int | float | bool)} for c in configs
            if c.get("interface") not in SOFTWARE_BUSES]


def find_ports(timeout_s: float = 5.0) -> dict:
    """Everything above: {"socketcan": [...], "serial": [...], "python_can": [...]}."""
    return {"socketcan": socketcan_links(), "serial": serial_adapters(), "python_can": python_can_configs(timeout_s)}
