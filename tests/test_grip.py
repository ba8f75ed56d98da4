"""The simulated gripper's hold (sim_fallback/grip.py) on objects the tests build between its fingers
(tests/grip_objects.py): it holds whatever link the fingers close on, its pads' friction sets the force it holds,
and a round knob turns in the fingers under a twist a bar holds."""

from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pybullet as pb
import pytest
from grip_objects import object_at_tool

from drivers.arm.motion import follow_cartesian_path, line_path
from drivers.arm.trajectory import MotionLimits
from sim_fallback.arm import SimArm
from sim_fallback.scenario import Scenario
from sim_fallback.world import SimWorld

GRIP_FORCE_N = 40.0
PULL = MotionLimits(0.05, 0.3, 3.0)


@contextmanager
def _gripped(tmp_path: Path, handle: str, joint: str, pad_friction: float = 0.6) -> Iterator[tuple]:
    """A world, its arm (pads of `pad_friction`) and an object (`handle` on `joint`) the closed gripper holds."""
    with SimWorld(Scenario.make("drawer", 0, "train")) as world:
        arm = SimArm(world, pad_friction=pad_friction)
        body = object_at_tool(world.client, arm.kin.fk(arm.state().q), handle, joint, tmp_path)
        arm.set_gripper(0.0, GRIP_FORCE_N)
        for _ in range(120):
            arm.sync()
        yield world, arm, body


def _joint(world, body) -> float:
    return float(pb.getJointState(body, 0, physicsClientId=world.client)[0])


def _push(world, arm, body, force: np.ndarray | None = None, torque: np.ndarray | None = None,
          ticks: int = 240) -> None:
    """Push the object's moving link with a force (N) or torque (N m, world axes) for `ticks` physics steps."""
    for _ in range(ticks):
        if force is not None:
            at = pb.getLinkState(body, 0, physicsClientId=world.client)[0]
            pb.applyExternalForce(body, 0, force.tolist(), at, pb.WORLD_FRAME, physicsClientId=world.client)
        if torque is not None:
            pb.applyExternalTorque(body, 0, torque.tolist(), pb.WORLD_FRAME, physicsClientId=world.client)
        arm.sync()


@pytest.mark.parametrize("handle", ["bar", "knob"])
def test_a_grip_holds_and_pulls_a_link_that_is_not_the_worlds_handle(tmp_path, handle):
    with _gripped(tmp_path, handle, "slide") as (world, arm, body):
        pb.setJointMotorControl2(body, 0, pb.VELOCITY_CONTROL, targetVelocity=0.0, force=10.0,
                                 physicsClientId=world.client)  # a drawer's friction
        width, start = arm.state().gripper_width_m, _joint(world, body)
        assert width > 0.01  # closed on the object, not on itself
        T = arm.kin.fk(arm.state().q)
        result = follow_cartesian_path(arm, arm.kin, line_path(T, -T[:3, 2]), 0.05, PULL)
        assert result.reason == "completed"
        assert _joint(world, body) - start == pytest.approx(0.05, abs=0.005)
        assert arm.state().gripper_width_m == pytest.approx(width, abs=1e-3)  # still holding it


@pytest.mark.parametrize("pad_friction", [0.4, 0.8])
def test_the_pads_friction_sets_the_force_the_grip_holds(tmp_path, pad_friction):
    """Pulled out of the fingers, the object stays below 2 mu F (two pads) and slips above it."""
    limit_n = 2 * pad_friction * GRIP_FORCE_N
    moved = {}
    for share in (0.8, 1.2):
        with _gripped(tmp_path, "bar", "slide", pad_friction) as (world, arm, body):
            start = _joint(world, body)
            out = -arm.kin.fk(arm.state().q)[:3, 2]  # out of the fingers
            _push(world, arm, body, force=share * limit_n * out)
            moved[share] = _joint(world, body) - start
            width = arm.state().gripper_width_m
        if share < 1:
            assert moved[share] < 0.002 and width > 0.01
        else:
            assert moved[share] > 0.01 and width < 0.011  # pulled out: the fingers close past the 12 mm bar


def test_a_round_knob_turns_in_the_fingers_under_a_twist_a_bar_holds(tmp_path):
    """The same twist about the closing direction: the bar's long contact holds it, the knob's short one does not
    (mu F span / 2: about 0.2 N m along a bar, under 0.1 N m on a 30 mm ball with these pads)."""
    turned = {}
    for handle in ("bar", "knob"):
        with _gripped(tmp_path, handle, "twist") as (world, arm, body):
            closing = arm.kin.fk(arm.state().q)[:3, 1]
            _push(world, arm, body, torque=0.15 * closing)
            turned[handle] = abs(np.degrees(_joint(world, body)))
            assert arm.state().gripper_width_m > 0.01  # the fingers still hold it
    assert turned["bar"] < 1.0 and turned["knob"] > 30.0
