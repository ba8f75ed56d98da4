"""Cabinet mechanisms applied every physics step: Coulomb friction and stiction, self-closing and soft-close springs,
magnetic catches with a break-away force, drawers that stop at their end; and seeded realistic values."""

from dataclasses import replace

import numpy as np
import pybullet as pb
import pytest
from sim_scenes import showroom

from sim_fallback.furniture import Mechanism
from sim_fallback.mechanisms import closing_force, random_mechanism
from sim_fallback.unit_families import random_carcass, random_look, random_unit
from sim_fallback.world import SimWorld


def one_part(layout: str, mechanism: Mechanism):
    """A unit whose first part has `mechanism`, alone in front of the robot."""
    rng = np.random.default_rng(11)
    unit = random_unit("base", layout, 0.5, random_carcass("train", "base", rng), random_look("train", rng, "bar"),
                       "train", rng, f"mechanism {layout}")
    unit = replace(unit, fronts=(replace(unit.fronts[0], mechanism=mechanism), *unit.fronts[1:]))
    return SimWorld(showroom([unit.furniture()], "drawer" if layout == "drawers" else "door"))


def push(world: SimWorld, effort: float, seconds: float) -> float:
    """Push the target part open with `effort` (N along a drawer's axis, N m about a door's) for `seconds`; its value
    after."""
    c, body, joint = world.client, world.cabinet_id, world.cabinet_joint
    axis = world.truth().direction
    for _ in range(int(seconds / world.clock.dt)):
        if world.truth().joint_type == "prismatic":
            centre = pb.getLinkState(body, joint, physicsClientId=c)[0]
            pb.applyExternalForce(body, joint, (effort * axis).tolist(), centre, pb.WORLD_FRAME, physicsClientId=c)
        else:
            pb.applyExternalTorque(body, joint, (effort * axis).tolist(), pb.WORLD_FRAME, physicsClientId=c)
        world.clock.step()
    return world.joint_value()


def test_stiction_holds_a_part_above_its_friction_until_it_moves():
    m = Mechanism(friction=8.0, damping=5.0, stiction=4.0)
    with one_part("drawers", m) as world:
        assert push(world, 10.0, 0.5) < 1e-3  # above the friction, below friction + stiction
        assert push(world, 16.0, 0.2) > 0.01  # breaks away
        moving = world.joint_value()
        assert push(world, 10.0, 0.3) > moving + 0.01  # once moving, friction alone resists


def test_a_drawer_stops_at_its_end():
    with one_part("drawers", Mechanism(friction=6.0, damping=3.0)) as world:
        upper = world.target.part.upper
        assert push(world, 60.0, 2.0) == pytest.approx(upper, abs=0.005)


def test_a_soft_close_drawer_pulls_itself_shut_from_its_range_only():
    m = Mechanism(friction=6.0, damping=5.0, soft_close_range=0.05, soft_close_force=15.0)
    with one_part("drawers", m) as world:
        c = world.client
        pb.resetJointState(world.cabinet_id, world.cabinet_joint, 0.03, physicsClientId=c)
        assert push(world, 0.0, 1.0) < 0.002
        assert push(world, 18.0, 0.5) < 1e-3  # held shut against more than its friction
        pb.resetJointState(world.cabinet_id, world.cabinet_joint, 0.12, physicsClientId=c)
        assert push(world, 0.0, 1.0) == pytest.approx(0.12, abs=1e-3)


def test_a_self_closing_door_returns():
    m = Mechanism(friction=0.4, damping=0.5, spring_preload=1.2, spring_stiffness=0.4)
    with one_part("door", m) as world:
        pb.resetJointState(world.cabinet_id, world.cabinet_joint, 1.2, physicsClientId=world.client)
        assert push(world, 0.0, 4.0) < 0.02


def test_a_magnetic_catch_holds_until_its_break_away_force():
    m = Mechanism(friction=0.5, damping=0.5, catch_range=0.05, catch_force=2.0)
    with one_part("door", m) as world:
        assert push(world, 2.2, 1.0) < 0.01  # above the friction, below the catch and friction
        assert push(world, 3.0, 1.0) > 0.3  # past the break-away force it swings open
        pb.resetJointState(world.cabinet_id, world.cabinet_joint, 0.03, physicsClientId=world.client)
        assert push(world, 0.0, 1.0) < 0.005  # near closed, it snaps shut


def test_closing_forces_add_up_as_documented():
    m = Mechanism(spring_preload=1.0, spring_stiffness=2.0, soft_close_range=0.1, soft_close_force=3.0,
                  catch_range=0.02, catch_force=4.0)
    assert closing_force(m, 0.0) == pytest.approx(1.0 + 3.0 + 4.0)
    assert closing_force(m, 0.01) == pytest.approx(1.0 + 0.02 + 3.0 + 2.0)
    assert closing_force(m, 0.5) == pytest.approx(2.0)
    assert closing_force(Mechanism(), -1e-9) == 0.0


def test_seeded_mechanisms_are_realistic():
    rng = np.random.default_rng(0)
    drawers = [random_mechanism("drawer", 0.0, rng) for _ in range(300)]
    start = np.array([m.friction + m.stiction for m in drawers])
    assert 5.0 <= start.min() and start.max() <= 20.0  # N to start a drawer moving
    soft = [m for m in drawers if m.soft_close_force]
    assert 0.3 < len(soft) / len(drawers) < 0.7 and all(0.02 <= m.soft_close_range <= 0.06 for m in soft)
    lever = 0.4
    doors = [random_mechanism("door", lever, rng) for _ in range(300)]
    assert all(1.0 <= m.friction / lever <= 3.0 for m in doors)  # N at the handle
    catches = [m for m in doors if m.catch_force]
    assert catches and all(3.0 <= m.catch_force / lever <= 8.0 for m in catches)  # a few N of break-away
    springs = [m for m in doors if m.spring_preload]
    assert springs and all(m.spring_preload > m.friction + m.stiction for m in springs)  # it does close
    assert random_mechanism("door", lever, np.random.default_rng(4)) == random_mechanism(
        "door", lever, np.random.default_rng(4))
