"""A real arm's command reaches a real bus or refuses: `--arm can` never falls back to a simulation config, never
runs on python-can's virtual bus or a Linux vcan link, and not one frame reaches such a bus."""

import can
import pytest

from deploy.cli import main
from drivers.arm.registry import open_arm
from drivers.arm.robot_config import PANDA_SIM_CONFIG, load_robot_config
from drivers.errors import ArmError
from tests.cli_run import one_line, run

ARM_COMMANDS = [
    ["arm", "scan"],
    ["arm", "status"],
    ["arm", "enable", "--yes"],
    ["arm", "disable"],
    ["arm", "zero", "--joint", "panda_joint1", "--yes"],
    ["arm", "home", "--yes"],
    ["arm", "jog", "--joint", "panda_joint1", "--delta", "0.1", "--yes"],
    ["arm", "move", "--pose", "0.45", "0.0", "0.6", "0", "90", "0", "--yes"],
]
RIG_COMMANDS = [
    ["open-drawer", "--camera", "d415:000000000000"],
    ["record", "--camera", "d415:000000000000", "--out", "never-written", "--frames", "3"],
    ["calibrate", "hand-eye", "--camera", "d415:000000000000", "--pivot-mm", "0", "0", "30", "--yes"],
]


@pytest.fixture
def panda_bus():
    """A second endpoint on the simulated Panda's virtual channel: sees every frame any command sends there."""
    bus = can.Bus(interface="virtual", channel=load_robot_config(PANDA_SIM_CONFIG).can.channel,
                  receive_own_messages=False)
    yield bus
    bus.shutdown()


@pytest.mark.parametrize("command", ARM_COMMANDS + RIG_COMMANDS, ids=lambda c: " ".join(c[:2]))
def test_every_real_arm_command_without_robot_refuses_and_sends_nothing(command, panda_bus, capsys, tmp_path,
                                                                        monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, *command, "--arm", "can")
    assert code == 2 and "--arm can needs --robot CONFIG.toml" in one_line(err)
    assert "sim-can" in err  # names what to use without hardware
    assert panda_bus.recv(timeout=0.05) is None
    assert not (tmp_path / "never-written").exists()


def _on(tmp_path, interface: str, channel: str):
    text = PANDA_SIM_CONFIG.read_text()
    path = tmp_path / f"{interface}.toml"
    path.write_text(text.replace('interface = "virtual"', f'interface = "{interface}"')
                    .replace('channel = "axisloop-sim"', f'channel = "{channel}"'))
    return path


@pytest.mark.parametrize("command", ARM_COMMANDS + RIG_COMMANDS, ids=lambda c: " ".join(c[:2]))
def test_every_real_arm_command_refuses_a_config_on_the_virtual_bus(command, panda_bus, capsys, tmp_path,
                                                                    monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, _, err = run(capsys, *command, "--arm", "can", "--robot", "panda_sim")
    line = one_line(err)
    assert code == 2 and "interface 'virtual', channel 'axisloop-sim', where no real motor is" in line
    assert "--arm sim-can" in line
    assert panda_bus.recv(timeout=0.05) is None


def test_a_vcan_link_is_not_a_real_bus_either(capsys, tmp_path):
    code, _, err = run(capsys, "arm", "disable", "--arm", "can", "--robot", _on(tmp_path, "socketcan", "vcan0"))
    assert code == 2 and "interface 'socketcan', channel 'vcan0', where no real motor is" in one_line(err)


def test_the_driver_refuses_a_virtual_bus_below_the_cli():
    config = load_robot_config(PANDA_SIM_CONFIG)
    with pytest.raises(ArmError, match="where no real motor is"):
        open_arm("can", config)
    real = config.model_copy(update={"can": config.can.model_copy(update={"interface": "socketcan",
                                                                          "channel": "can0"})})
    assert not real.can.virtual and open_arm("sim-can", config) is not None  # the simulated kind keeps its bus


def test_simulated_arms_still_default_to_the_simulated_panda(capsys):
    code, out, _ = run(capsys, "arm", "scan", "--arm", "sim-can", "--json")
    assert code == 0 and '"can_id": 1' in out
    assert main(["arm", "scan", "--arm", "sim-can", "--last-id", "1"]) == 0
