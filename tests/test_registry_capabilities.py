"""Decisions taken from registry entries' properties, never from kind names: a plug-in camera, arm or estimator is
accepted wherever a shipped one of the same kind is (calibration devices, stream options, bring-up's bare bus,
--sim-fault, the config's estimator name); and a CAN arm whose connect fails closes its bus."""

import itertools

import pytest

from deploy.arm_bringup import parse_sim_faults, raw_bus
from deploy.calibration_devices import choose
from deploy.config import load_config
from deploy.errors import ConfigError
from deploy.geometry.estimators.registry import ESTIMATORS
from deploy.rig import bare_bus
from drivers.arm.can_arm import CanArm
from drivers.arm.can_bus import CanBus
from drivers.arm.registry import ARMS
from drivers.arm.robot_config import PANDA_SIM_CONFIG, load_robot_config, robot_config_path
from drivers.camera.registry import CAMERAS, stream_options
from drivers.errors import ArmError
from drivers.registry import Entry

PANDA = load_robot_config(PANDA_SIM_CONFIG)
_channels = itertools.count()


def _add(monkeypatch, registry, name: str, **fields) -> None:
    """Register kind `name` for this test only (removed afterwards)."""
    registry.entries()  # plug-ins first, so that they cannot replace it
    monkeypatch.setitem(registry._entries, name, Entry(name, f"{__name__}:unused", "a plug-in kind", **fields))


class FakeBus:
    closed = False

    def close(self) -> None:
        self.closed = True


class FakeMotors(FakeBus):
    pass


def open_fake_bus(robot):
    return FakeBus(), FakeMotors()


def test_a_plug_in_camera_calibrates_with_the_hardware_arm(monkeypatch):
    _add(monkeypatch, CAMERAS, "usb3d", hardware=True, argument="[:SERIAL]")
    choice = choose("usb3d:42", None, robot_config_path("damiao_6dof"), (0.0, 0.0, 30.0))
    assert choice.arm == "can" and choice.real_arm and not choice.simulated  # the first hardware arm by default


def test_a_plug_in_simulated_camera_pairs_with_simulated_arms_only(monkeypatch):
    _add(monkeypatch, CAMERAS, "sim2", simulated=True)
    assert choose("sim2", None, None).arm == "sim"
    with pytest.raises(ConfigError, match="--camera sim2 needs a simulated arm .*cannot see --arm can"):
        choose("sim2", "can", PANDA_SIM_CONFIG, (0.0, 0.0, 30.0))


def test_a_kind_that_is_neither_simulated_nor_hardware_cannot_calibrate(monkeypatch):
    _add(monkeypatch, CAMERAS, "archive", argument=":PATH")
    with pytest.raises(ConfigError,
                       match=r"'archive:/x' is not one of sim, realsense\[:SERIAL\], d415.*a recording cannot show"):
        choose("archive:/x", None, None)


def test_stream_options_follow_the_entry(monkeypatch):
    _add(monkeypatch, CAMERAS, "thermal", hardware=True, stream_options=("fps",))
    asked = {"width": 320, "height": 240, "fps": 9}
    assert stream_options("thermal", asked) == {"fps": 9}
    assert stream_options("d415", asked) == asked and stream_options("sim", asked) == asked
    assert stream_options("replay:/nowhere", asked) == {}


def test_bring_up_opens_a_plug_in_arms_bus_from_its_entry(monkeypatch):
    _add(monkeypatch, ARMS, "sim-can2", simulated=True, bus=f"{__name__}:open_fake_bus")
    with bare_bus("sim-can2", PANDA) as (bus, motors):
        assert not bus.closed
    assert bus.closed and motors.closed
    faults = parse_sim_faults("sim-can2", ["bus-off@1"])  # a simulated kind with a bus: its motors can be broken
    scheduled = []
    monkeypatch.setattr(type(faults[0]), "schedule", lambda fault, on: scheduled.append((fault.kind, on)))
    with raw_bus(PANDA, "sim-can2", faults):
        assert [kind for kind, _ in scheduled] == ["bus-off"] and isinstance(scheduled[0][1], FakeMotors)
    with pytest.raises(ConfigError, match="use it with --arm sim-can or sim-can2, not --arm can"):
        parse_sim_faults("can", ["bus-off"])


def test_an_arm_without_a_bus_is_refused_by_bring_up_commands():
    with pytest.raises(ArmError, match="needs --arm can or sim-can, not 'ideal'"), bare_bus("ideal", PANDA):
        pass


def test_the_estimator_name_is_checked_against_the_registry(monkeypatch):
    with pytest.raises(ConfigError, match="estimator.name: unknown estimator 'magic': choose one of screw-grip"):
        load_config(None, {"estimator.name": "magic"})
    _add(monkeypatch, ESTIMATORS, "my-fit")
    assert load_config(None, {"estimator.name": "my-fit"}).estimator.name == "my-fit"


def test_a_failed_connect_closes_the_bus_and_reports_the_motors():
    can = PANDA.can.model_copy(update={"channel": f"nobody-{next(_channels)}"})  # nothing answers here
    arm = CanArm(PANDA.model_copy(update={"can": can}), CanBus.from_config(can))
    with pytest.raises(ArmError, match="did not answer") as caught, arm:
        pass
    assert arm.bus._closed and len(caught.value.motors) == len(PANDA.motors)
