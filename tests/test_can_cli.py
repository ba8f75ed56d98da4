"""CAN from the command line: --interface, --channel, --bitrate and --data-bitrate over the robot config's [can] on
every arm command, open*, record and calibrate (the real-bus rule applying to the result), and `deploy arm
find-port` (SocketCAN links, serial adapters with their USB ids, python-can's detected configs)."""

import json
import os

import can
import pytest

from deploy.rig import load_robot
from drivers.arm.can_ports import serial_adapters, socketcan_links
from tests.cli_run import one_line, run
from tests.test_real_bus import ARM_COMMANDS, RIG_COMMANDS

OPENARM_COMMANDS = [[*c[:3], "openarm_right_joint1", *c[4:]] if "--joint" in c else c for c in ARM_COMMANDS]


@pytest.fixture
def listener():
    """An endpoint on the virtual channel the overrides point at: sees every frame sent there."""
    bus = can.Bus(interface="virtual", channel="override-test", receive_own_messages=False)
    yield bus
    bus.shutdown()


@pytest.mark.parametrize("command", OPENARM_COMMANDS + RIG_COMMANDS, ids=lambda c: " ".join(c[:2]))
def test_an_override_onto_a_virtual_bus_is_refused_and_sends_nothing(command, listener, capsys, tmp_path,
                                                                     monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, *command, "--arm", "can", "--robot", "openarm", "--interface", "virtual",
                       "--channel", "override-test")
    line = one_line(err)
    assert code == 2 and "--interface virtual --channel override-test is a virtual bus" in line
    assert "deploy arm find-port" in line and "--arm sim-can" in line
    assert listener.recv(timeout=0.05) is None
    assert not (tmp_path / "never-written").exists()


def test_overrides_replace_the_configs_can_settings():
    config = load_robot("can", "openarm", (("interface", "pcan"), ("channel", "PCAN_USBBUS1"), ("bitrate", 500_000)))
    assert (config.can.interface, config.can.channel, config.can.bitrate) == ("pcan", "PCAN_USBBUS1", 500_000)
    assert config.can.fd and config.can.data_bitrate == 5_000_000  # the rest stays the config's
    classic = load_robot("can", "damiao_6dof", (("data_bitrate", 2_000_000), ("fd", True)))
    assert classic.can.fd and classic.can.data_bitrate == 2_000_000
    assert load_robot("sim-can", None, ()).can == load_robot("sim-can", None).can


def test_a_bad_override_is_one_line(capsys):
    code, _, err = run(capsys, "arm", "status", "--arm", "can", "--robot", "openarm", "--bitrate", "0")
    assert code == 2 and "--bitrate" in err


def test_an_override_reaches_the_bus_the_driver_opens(capsys):
    """A socketcan channel that is not on this machine: the command tries that channel (not the config's can0)."""
    code, _, err = run(capsys, "arm", "scan", "--arm", "can", "--robot", "openarm", "--channel", "can7")
    assert code == 2 and "channel 'can7' cannot be opened" in one_line(err)


def test_the_damiao_dongle_interface_names_its_plug_in(capsys):
    code, _, err = run(capsys, "arm", "scan", "--arm", "can", "--robot", "openarm", "--interface", "damiao",
                       "--channel", "/dev/ttyACM9")
    line = one_line(err)
    assert code == 2 and "damiao" in line
    assert "pip install python-can-damiao" in line or "'/dev/ttyACM9' cannot be opened" in line


def test_sim_can_runs_openarm_over_can_fd_with_the_overrides(capsys):
    code, out, _ = run(capsys, "arm", "scan", "--arm", "sim-can", "--robot", "openarm", "--data-bitrate", "2000000",
                       "--json")
    assert code == 0 and [m["fd"] for m in json.loads(out)["motors"]] == [True] * 8


# --- find-port ---------------------------------------------------------------------------------------------------

IP_LINKS = [  # `ip -details -json link` entries (iproute2's keys) of a loopback, a CAN FD adapter and a vcan link
    {"ifname": "lo", "flags": ["LOOPBACK", "UP"], "link_type": "loopback", "operstate": "UNKNOWN"},
    {"ifname": "can0", "flags": ["NOARP", "UP", "LOWER_UP", "ECHO"], "mtu": 72, "link_type": "can",
     "operstate": "UP", "linkinfo": {"info_kind": "can", "info_data": {
         "ctrlmode": ["FD"], "state": "ERROR-ACTIVE", "bittiming": {"bitrate": 1000000, "sample_point": "0.800"},
         "data_bittiming": {"bitrate": 5000000, "sample_point": "0.750"}}}},
    {"ifname": "vcan0", "flags": ["NOARP", "UP", "LOWER_UP"], "mtu": 72, "link_type": "can", "operstate": "UNKNOWN",
     "linkinfo": {"info_kind": "vcan"}},
]


def test_socketcan_links_are_read_from_ip_link():
    assert socketcan_links(IP_LINKS) == [
        {"name": "can0", "kind": "can", "up": True, "state": "ERROR-ACTIVE", "bitrate": 1000000,
         "data_bitrate": 5000000, "fd": True},
        {"name": "vcan0", "kind": "vcan", "up": True, "state": "UNKNOWN", "bitrate": None, "data_bitrate": None,
         "fd": True},
    ]


def test_serial_adapters_carry_their_usb_ids_and_the_damiao_dongle_is_named(tmp_path):
    dev, sys_tty = tmp_path / "dev", tmp_path / "sys" / "class" / "tty"
    usb = tmp_path / "sys" / "devices" / "usb1" / "1-2"
    for name, (vid, pid, product) in {"ttyACM0": ("2e88", "4603", "HDSC CDC Device"),
                                      "ttyUSB0": ("0403", "6001", "FT232R USB UART")}.items():
        (dev / name).parent.mkdir(parents=True, exist_ok=True)
        (dev / name).touch()
        device = usb / f"{name}-if" / "1-2:1.0"
        device.mkdir(parents=True)
        (device.parent / "idVendor").write_text(vid + "\n")
        (device.parent / "idProduct").write_text(pid + "\n")
        (device.parent / "product").write_text(product + "\n")
        (sys_tty / name).mkdir(parents=True)
        os.symlink(device, sys_tty / name / "device")
    found = {a["device"].rsplit("/", 1)[1]: a for a in serial_adapters(dev, sys_tty)}
    assert found["ttyACM0"]["usb_id"] == "2e88:4603" and found["ttyACM0"]["adapter"] == "Damiao USB-CAN"
    assert found["ttyACM0"]["interface"] == "damiao"
    assert found["ttyUSB0"]["usb_id"] == "0403:6001" and found["ttyUSB0"]["interface"] is None
    assert found["ttyUSB0"]["product"] == "FT232R USB UART"


def test_find_port_on_this_machine(capsys):
    code, out, err = run(capsys, "arm", "find-port", "--json")
    data = json.loads(out)
    assert code == 0 and set(data) == {"socketcan", "serial", "python_can"} and "Traceback" not in err
    assert data["socketcan"] == socketcan_links()  # what `ip link` shows here
    assert data["serial"] == serial_adapters()
    assert all(c["interface"] not in ("virtual", "udp_multicast") for c in data["python_can"])
    code, out, _ = run(capsys, "arm", "find-port")
    assert code == 0 and ("SocketCAN links" in out or "no SocketCAN link" in out)
