"""The force limit of compliant pulls (drivers/arm/motion.py, `Compliance`), held on both sides of each boundary on
the simulated arm (sim) and on the CAN driver over simulated motors (sim-can), with PyBullet's exact joint torques:
the real motion code pulls the tool along a line while PyBullet pushes it back with a known force, switched on after
the pull began (the pull's force is what it adds to the force held when it began). With the torques measured as
Damiao motors measure them (their offset measured free first, as an episode does) the boundaries hold within the
sensing's noise.

Boundaries, with the default limit of 60 N ([opening] pull_force_limit_n): full speed below half the limit; slower
past half; a halt at 85 % (backing off above, so the force settles there on an object that does not give); "blocked"
when held still for 0.3 s, or at once above the limit, with the peak force reported."""

import re

import numpy as np
import pybullet as pb
import pytest

from drivers.arm.motion import HELD_FORCE_S, Outcome, PathResult, follow_cartesian_path, line_path
from drivers.arm.registry import open_arm
from drivers.arm.robot_config import load_robot_config
from drivers.arm.trajectory import MotionLimits
from drivers.arm.wrench import torque_offset
from sim_fallback.arm import PAD_FRICTION, SimArm
from sim_fallback.devices import EpisodeSignals, sim_can_arm
from sim_fallback.scenario import Scenario
from sim_fallback.world import SimWorld

PANDA = load_robot_config("panda_sim")
LIMIT_N = 60.0
COMPLIANCE = PANDA.compliance.gains().with_force_limit(LIMIT_N)
PULL = np.array([-1.0, 0.0, 0.0])  # from the ready pose toward the base: free space
LENGTH_M = 0.06
SPEED = MotionLimits(0.05, 0.25, 2.5)  # 1.5 s unhindered
SETTLE_TICKS = 480  # the arm at rest (its torques settled: the last quarter measures their offset) before the pull
ON_AT_S = 0.2  # the push starts this long into the pull
DEADLINE_S = 20.0  # arm seconds: a pull that never ends is stopped here (and fails its test)
KINDS = ["sim", "sim-can"]
EXACT = EpisodeSignals(torque_sensing=None, pad_friction=PAD_FRICTION)


def _pull(kind: str, force_n: float, on_s: float = ON_AT_S, off_s: float = np.inf,
          measured: bool = False) -> PathResult:
    """A compliant pull of LENGTH_M along PULL while the world pushes the tool back with `force_n` from `on_s` to
    `off_s` seconds after the pull began (negative: already during the settling before it); the joint torques
    exact, or `measured` as the episode's Damiao motors measure them."""
    with SimWorld(Scenario.make("drawer", 0, "train")) as world:
        if measured:
            arm = open_arm(kind, PANDA, world=world)
        else:
            arm = SimArm(world) if kind == "sim" else sim_can_arm(PANDA, world, signals=EXACT)[0]
        with arm:
            tool = world.robot_joints["panda_grasptarget_hand"]
            start = [world.clock.time + SETTLE_TICKS * arm.control_period_s]

            def push() -> None:
                if on_s <= world.clock.time - start[0] < off_s:
                    p = pb.getLinkState(world.robot_id, tool, physicsClientId=world.client)[0]
                    pb.applyExternalForce(world.robot_id, tool, (-force_n * PULL).tolist(), p, pb.WORLD_FRAME,
                                          physicsClientId=world.client)

            world.clock.add_hook(push)
            at_rest = []
            for _ in range(SETTLE_TICKS):
                arm.sync()
                at_rest.append(arm.state())
            compliance = COMPLIANCE if on_s < 0 else \
                COMPLIANCE.with_torque_offset(torque_offset(arm.kin, at_rest[-SETTLE_TICKS // 4:]))  # free: tared
            start[0] = world.clock.time + HELD_FORCE_S  # the pull holds still that long, then moves
            return follow_cartesian_path(arm, arm.kin, line_path(arm.kin.fk(arm.state().q), PULL), LENGTH_M, SPEED,
                                         lambda _state, t: t < DEADLINE_S, sample_every=1, compliance=compliance)


def _duration_s(result: PathResult) -> float:
    return float(result.t[-1])


def _reason_forces(result: PathResult) -> tuple[float, float]:
    """(the force that ended the pull, the peak) as its reason states them."""
    match = re.fullmatch(r"blocked: pull force ([\d.]+) N.* at s = [\d.]+, peak ([\d.]+) N", result.reason)
    assert match, result.reason
    return float(match[1]), float(match[2])


@pytest.fixture(scope="module", params=KINDS)
def unhindered(request) -> tuple[str, PathResult]:
    return request.param, _pull(request.param, 0.0)


def test_an_unhindered_pull_runs_at_full_speed_and_feels_almost_nothing(unhindered):
    _, free = unhindered
    assert free.outcome is Outcome.COMPLETED and free.s_reached == pytest.approx(LENGTH_M)
    assert free.peak_force_n < 0.1 * LIMIT_N and _duration_s(free) < 1.6


def test_below_half_the_limit_the_pull_keeps_its_speed_past_half_it_slows(unhindered):
    kind, free = unhindered
    under = _pull(kind, 0.4 * LIMIT_N)
    past = _pull(kind, 0.65 * LIMIT_N)
    assert under.outcome is past.outcome is Outcome.COMPLETED
    assert _duration_s(under) < 1.05 * _duration_s(free)
    assert _duration_s(past) > 1.3 * _duration_s(free)
    assert 0.5 * LIMIT_N < past.peak_force_n < 0.85 * LIMIT_N


@pytest.mark.parametrize("kind", KINDS)
def test_just_below_the_halt_the_pull_goes_on_just_above_it_backs_off_and_ends_blocked(kind):
    below = _pull(kind, 0.8 * LIMIT_N)  # halts at 85 %: 80 % still creeps forward, to the end
    assert below.outcome is Outcome.COMPLETED and below.s_reached == pytest.approx(LENGTH_M)
    assert below.peak_force_n < 0.85 * LIMIT_N
    above = _pull(kind, 0.9 * LIMIT_N)  # above 85 %: backs off along the path, held still 0.3 s: blocked
    force, peak = _reason_forces(above)
    assert above.outcome is Outcome.BLOCKED and "held the path still for 0.3 s" in above.reason
    assert 0.85 * LIMIT_N < force < LIMIT_N and peak == pytest.approx(above.peak_force_n, abs=0.05)
    assert above.s_reached < float(above.s.max()) - 0.001  # it backed off
    assert above.s_reached < 0.5 * LENGTH_M


@pytest.mark.parametrize("kind", KINDS)
def test_a_steady_force_just_below_the_limit_is_held_just_above_it_blocks_at_once(kind):
    below = _pull(kind, 0.95 * LIMIT_N)
    force, _ = _reason_forces(below)
    assert below.outcome is Outcome.BLOCKED and "held the path still for 0.3 s" in below.reason and force < LIMIT_N
    above = _pull(kind, 1.05 * LIMIT_N)
    force, peak = _reason_forces(above)
    assert above.outcome is Outcome.BLOCKED and f"> limit {LIMIT_N:.0f} N" in above.reason
    assert LIMIT_N <= force <= peak and peak == pytest.approx(above.peak_force_n, abs=0.05)  # force: to 0.1 N
    assert _duration_s(above) < _duration_s(below)  # no 0.3 s of waiting: at once


@pytest.mark.parametrize("kind", KINDS)
def test_a_brief_force_just_below_the_limit_is_ridden_out_just_above_it_blocks(kind):
    below = _pull(kind, 0.95 * LIMIT_N, 0.3, 0.5)
    assert below.outcome is Outcome.COMPLETED and below.s_reached == pytest.approx(LENGTH_M)
    assert 0.85 * LIMIT_N < below.peak_force_n < LIMIT_N
    above = _pull(kind, 1.1 * LIMIT_N, 0.3, 0.5)
    force, peak = _reason_forces(above)
    assert above.outcome is Outcome.BLOCKED and f"> limit {LIMIT_N:.0f} N" in above.reason
    assert LIMIT_N <= force <= peak and peak == pytest.approx(above.peak_force_n, abs=0.05)  # force: to 0.1 N
    assert above.s_reached < 0.5 * LENGTH_M


@pytest.mark.parametrize("kind", KINDS)
def test_a_force_held_before_the_pull_began_is_not_the_pulls(kind):
    """A grasp's squeeze, the weight of what the tool holds: 90 % of the limit from before the pull, and the pull
    adds nothing to it."""
    result = _pull(kind, 0.9 * LIMIT_N, on_s=-1.0)
    assert result.outcome is Outcome.COMPLETED and result.peak_force_n < 0.1 * LIMIT_N


@pytest.mark.parametrize("kind", KINDS)
def test_with_torques_measured_as_motors_measure_them_the_boundaries_hold_within_the_noise(kind):
    """Noise of 1-2 N at the tool on top of the motion's own force (docs/benchmarks.md, wrench noise): an unhindered
    pull still feels little, 40 % of the limit keeps the speed, 65 % slows it, 105 % blocks at once."""
    free = _pull(kind, 0.0, measured=True)
    assert free.outcome is Outcome.COMPLETED and free.peak_force_n < 0.15 * LIMIT_N
    under, past = _pull(kind, 0.4 * LIMIT_N, measured=True), _pull(kind, 0.65 * LIMIT_N, measured=True)
    assert _duration_s(under) < 1.05 * _duration_s(free) < _duration_s(past) / 1.3
    above = _pull(kind, 1.05 * LIMIT_N, measured=True)
    assert above.outcome is Outcome.BLOCKED and f"> limit {LIMIT_N:.0f} N" in above.reason
