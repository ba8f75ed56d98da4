"""The shape of the `deploy` CLI: every command is a module-level function of deploy/commands/ that Python can
call with the command's arguments, and shared flags are spelled the same in every group."""

import sys

import numpy as np
import pytest
from typer.main import get_command

from deploy.cli import app, main
from deploy.commands import axis


def _commands(typer_app):
    for info in typer_app.registered_commands:
        yield info.callback
    for group in typer_app.registered_groups:
        yield from _commands(group.typer_instance)


def test_every_command_is_a_module_level_function_of_deploy_commands():
    callbacks = list(_commands(app))
    assert len(callbacks) >= 30
    for f in callbacks:
        assert f.__module__.startswith("deploy.commands."), f
        assert getattr(sys.modules[f.__module__], f.__name__) is f, f"{f.__module__}.{f.__name__} is not module-level"


def test_yes_is_yes_or_y_in_every_group():
    def walk(command, path):
        for param in command.params:
            if param.name == "yes":
                yield path, param.opts
        for name, sub in getattr(command, "commands", {}).items():
            yield from walk(sub, (*path, name))

    found = dict(walk(get_command(app), ()))
    assert {("open-drawer",), ("arm", "home"), ("calibrate", "hand-eye")} <= set(found)
    for path, opts in found.items():
        assert sorted(opts) == ["--yes", "-y"], path


@pytest.mark.parametrize("json_out", [True, False])
def test_python_call_prints_what_the_command_prints(capsys, tmp_path, json_out):
    angles = np.radians(np.linspace(0, 40, 25))
    pts = np.c_[0.5 + 0.4 * np.cos(angles), 0.1 + 0.4 * np.sin(angles), np.full_like(angles, 0.7)]
    path = tmp_path / "arc.txt"
    path.write_text("\n".join(" ".join(f"{v:.6f}" for v in p) for p in pts) + "\n")

    assert main(["axis", "fit-trajectory", str(path), "--joint", "revolute"] + (["--json"] if json_out else [])) == 0
    from_cli = capsys.readouterr().out
    axis.axis_fit_trajectory(path, joint=axis.JointChoice.revolute, json_out=json_out)
    assert capsys.readouterr().out == from_cli
    assert "revolute" in from_cli and "radius" in from_cli
