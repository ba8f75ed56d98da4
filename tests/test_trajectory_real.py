"""fit_trajectory on paths like real recordings: each failure class of hand-recorded handle trajectories."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from deploy.bench.axis_paths import bench_axis_paths
from deploy.geometry.estimators.trajectory import (
    LEVEL_SIGMA_DEG,
    MAX_HINGE_SIGMA_DEG,
    fit_trajectory,
    fit_trajectory_report,
    level_hinge,
    parse_trajectory,
)
from deploy.geometry.metrics import axis_angle_error_deg
from deploy.geometry.types import Axis, JointType, NoAxis
from deploy.synthetic.handle_paths import handle_path_set, random_object, record_path

HZ = 60.0


def unit(v) -> np.ndarray:
    v = np.asarray(v, float)
    return v / np.linalg.norm(v)


def progress(n: int, pauses: int = 0, seed: int = 0) -> np.ndarray:
    """0..1 over n samples, minimum-jerk, with `pauses` stretches of 25 % of the samples standing still."""
    rng = np.random.default_rng(seed)
    moving = n - pauses * (n // 4)
    s = np.linspace(0, 1, moving)
    values = list(10 * s**3 - 15 * s**4 + 6 * s**5)
    for _ in range(pauses):
        at = int(rng.integers(1, len(values) - 1))
        values[at:at] = [values[at]] * (n // 4)
    return np.array(values)


def tremor(n: int, amplitude_m: float, seed: int) -> np.ndarray:
    """Band-limited (5-12 Hz) hand tremor sampled at HZ: (n,3) of RMS `amplitude_m` per axis."""
    rng = np.random.default_rng(seed)
    t = np.arange(n)[:, None, None] / HZ
    f, phase = rng.uniform(5, 12, (6, 3)), rng.uniform(0, 2 * np.pi, (6, 3))
    return amplitude_m * np.sqrt(2 / 6) * np.sum(np.sin(2 * np.pi * f * t + phase), axis=1)


def drawer(direction=(-1.0, 0.2, 0.0), travel_m=0.3, n=240, pauses=0, seed=0):
    """Positions and a constant orientation of a handle pulled along `direction`."""
    q = progress(n, pauses, seed) * travel_m
    positions = np.array([0.7, 0.1, 0.6]) + np.outer(q, unit(direction))
    quaternions = np.tile(Rotation.from_euler("xyz", [5, 80, 0], degrees=True).as_quat(), (n, 1))
    return positions, quaternions


def door(axis=(0.0, 0.0, 1.0), arc_deg=60.0, radius_m=0.45, n=240, pauses=0, seed=0):
    """Positions and orientations of a handle turning about a hinge through (0.8, 0.3, 0.5)."""
    axis = unit(axis)
    lever = unit(np.cross(axis, [0.3, 1.0, 0.2])) * radius_m
    turns = Rotation.from_rotvec(np.outer(np.radians(progress(n, pauses, seed) * arc_deg), axis))
    positions = np.array([0.8, 0.3, 0.5]) + turns.apply(lever)
    return positions, (turns * Rotation.from_euler("z", 20, degrees=True)).as_quat()


def jitter(positions, quaternions, seed, tremor_m=1.0e-3, sensor_m=0.4e-3, turn_deg=0.5):
    rng = np.random.default_rng(seed)
    noisy = positions + tremor(len(positions), tremor_m, seed) + rng.normal(0, sensor_m, positions.shape)
    rotations = Rotation.from_rotvec(np.radians(turn_deg) * rng.normal(size=(len(positions), 3)))
    return noisy, (rotations * Rotation.from_quat(quaternions)).as_quat()


def check(result, joint_type, direction, max_deg):
    assert isinstance(result, Axis), getattr(result, "reason", result)
    assert result.joint_type is joint_type
    assert axis_angle_error_deg(direction, result.direction) < max_deg
    assert result.direction_sigma_deg is not None and np.isfinite(result.direction_sigma_deg)


@pytest.mark.parametrize("with_orientation", [True, False])
def test_hand_jitter(with_orientation):
    for seed in range(4):
        positions, quaternions = jitter(*drawer(seed=seed), seed)
        check(fit_trajectory(positions, quaternions if with_orientation else None), JointType.PRISMATIC,
              [-1.0, 0.2, 0.0], 1.0)
        positions, quaternions = jitter(*door(seed=seed), seed)
        check(fit_trajectory(positions, quaternions if with_orientation else None), JointType.REVOLUTE,
              [0, 0, 1], 2.0)


def test_pauses_count_once():
    """Two long pauses (half the samples standing still, trembling) do not turn a slide into an arc."""
    for seed in range(4):
        positions, quaternions = jitter(*drawer(pauses=2, seed=seed), seed, tremor_m=1.5e-3)
        check(fit_trajectory(positions), JointType.PRISMATIC, [-1.0, 0.2, 0.0], 1.0)
        positions, quaternions = jitter(*door(pauses=2, seed=seed), seed, tremor_m=1.5e-3)
        check(fit_trajectory(positions, quaternions), JointType.REVOLUTE, [0, 0, 1], 2.0)


def test_short_travel_is_undecided_unless_the_joint_is_given():
    positions, _ = jitter(*drawer(travel_m=0.02, n=60), 0)
    result = fit_trajectory(positions)
    assert isinstance(result, NoAxis) and result.details["undecided"] and "travel" in result.reason
    assert fit_trajectory(positions, joint=JointType.PRISMATIC).joint_type is JointType.PRISMATIC


def test_a_short_arc_without_orientations_is_undecided_and_with_them_revolute():
    positions, quaternions = door(arc_deg=12, radius_m=0.5, n=120)
    result = fit_trajectory(positions)
    assert isinstance(result, NoAxis) and "too short an arc" in result.reason
    check(fit_trajectory(positions, quaternions), JointType.REVOLUTE, [0, 0, 1], 0.5)


@pytest.mark.parametrize("with_orientation", [True, False])
def test_tracking_glitches(with_orientation):
    rng = np.random.default_rng(3)
    for make, joint, direction in ((drawer, JointType.PRISMATIC, [-1.0, 0.2, 0.0]),
                                   (door, JointType.REVOLUTE, [0, 0, 1])):
        positions, quaternions = jitter(*make(seed=3), 3)
        picked = rng.choice(len(positions), 8, replace=False)
        positions[picked] += rng.normal(size=(8, 3)) * rng.uniform(0.03, 0.15, (8, 1))
        check(fit_trajectory(positions, quaternions if with_orientation else None), joint, direction, 2.0)


def wobbling_slide(seed: int, amplitude_m: float = 4e-3, wobble_deg: float = 2.5):
    """A sliding door moved 40 cm along its front, its handle swaying across the track and turning back
    and forth as the rollers pass (wavelength 25 cm)."""
    positions, quaternions = drawer(direction=(0.1, 1.0, 0.0), travel_m=0.4, seed=seed)
    along = (positions - positions[0]) @ unit([0.1, 1.0, 0.0])
    sway = np.sin(2 * np.pi * along / 0.25 + seed)
    positions = positions + amplitude_m * np.outer(sway - sway[0], [0.3, 0.0, 1.0])
    turn = Rotation.from_rotvec(np.outer(np.radians(wobble_deg) * (sway - sway[0]), [0.0, 0.0, 1.0]))
    return jitter(positions, (turn * Rotation.from_quat(quaternions)).as_quat(), seed)


def test_a_wobbling_sliding_part_is_never_called_revolute():
    for seed in range(5):
        positions, quaternions = wobbling_slide(seed)
        check(fit_trajectory(positions, quaternions), JointType.PRISMATIC, [0.1, 1.0, 0.0], 2.0)
        result = fit_trajectory(positions)
        assert isinstance(result, NoAxis) or result.joint_type is JointType.PRISMATIC


def test_a_tilted_hinge_keeps_its_tilt():
    for tilt in ([0.09, 0.0, 1.0], [0.0, -0.06, 1.0], [1.0, 0.0, 0.05]):  # 5, 3.4 deg off vertical; a flap
        for seed in range(3):
            positions, quaternions = jitter(*door(axis=tilt, arc_deg=50, seed=seed), seed)
            for q in (quaternions, None):
                check(fit_trajectory(positions, q), JointType.REVOLUTE, tilt, 1.5)


def swaying_hinge(axis, seed, sway_m=1.5e-3):
    """A positions-only 50 deg swing of 0.22 m about `axis` whose handle sways up to `sway_m` along the hinge
    midway (the part's play): from positions, a plane tilted about the chord, a hinge leaning a few degrees."""
    positions, _ = door(axis=axis, arc_deg=50, radius_m=0.22, seed=seed)
    drift = np.sin(np.pi * progress(len(positions), seed=seed))[:, None] * sway_m * unit(axis)
    return jitter(positions + drift, door()[1], seed)[0]


def lean_deg(direction, vertical: bool) -> float:
    """How far a hinge direction leans from vertical, or from horizontal."""
    height = abs(unit(direction)[2])
    return float(np.degrees(np.arccos(height) if vertical else np.arcsin(height)))


@pytest.mark.parametrize("axis", [[0.0, 0.0, 1.0], [1.0, 0.3, 0.0]], ids=["door", "flap"])
def test_play_along_a_level_hinge_is_levelled_with_the_world_up(axis):
    vertical = axis[2] == 1.0
    for seed in range(3):
        positions = swaying_hinge(axis, seed)
        leaning = fit_trajectory(positions, joint=JointType.REVOLUTE)
        assert lean_deg(leaning.direction, vertical) > 2.0  # the play leans the swing's plane
        levelled = fit_trajectory(positions, joint=JointType.REVOLUTE, up=np.array([0.0, 0.0, 1.0]))
        assert lean_deg(levelled.direction, vertical) < 0.8 * lean_deg(leaning.direction, vertical)
        assert axis_angle_error_deg(axis, levelled.direction) < axis_angle_error_deg(axis, leaning.direction)
        assert levelled.direction_sigma_deg < leaning.direction_sigma_deg


def test_level_hinge_pulls_the_lean_by_the_prior_and_keeps_what_is_built_slanted():
    up = np.array([0.0, 0.0, 1.0])
    leaning = Rotation.from_euler("x", 3, degrees=True).apply(up)
    direction, sigma = level_hinge(leaning, LEVEL_SIGMA_DEG, up)  # equal weights: half the lean, sigma / sqrt 2
    assert axis_angle_error_deg(up, direction) == pytest.approx(1.5, abs=1e-6)
    assert sigma == pytest.approx(LEVEL_SIGMA_DEG / np.sqrt(2))
    flap = unit([1.0, 0.5, 0.05])  # 2.6 deg from horizontal: levelled, its heading kept
    direction, sigma = level_hinge(flap, LEVEL_SIGMA_DEG, up)
    assert np.degrees(np.arcsin(direction @ up)) == pytest.approx(np.degrees(np.arcsin(flap @ up)) / 2, abs=1e-6)
    np.testing.assert_allclose(unit(direction[:2]), unit(flap[:2]), atol=1e-9)
    assert LEVEL_SIGMA_DEG / np.sqrt(2) < sigma < LEVEL_SIGMA_DEG
    slanted = Rotation.from_euler("y", 10, degrees=True).apply(up)  # a slanted lid, 10 deg > 3 combined sigmas
    np.testing.assert_array_equal(level_hinge(slanted, 1.0, up)[0], slanted)
    assert level_hinge(-up, 1.0, up)[0] @ -up == pytest.approx(1.0)  # the opening sense is kept


def test_a_hinge_built_at_a_slant_keeps_it_with_the_world_up():
    tilt = unit([0.0, 0.2, 1.0])  # 11 deg off vertical
    for seed in range(3):
        positions, quaternions = jitter(*door(axis=tilt, arc_deg=50, seed=seed), seed)
        check(fit_trajectory(positions, quaternions, up=np.array([0.0, 0.0, 1.0])), JointType.REVOLUTE, tilt, 1.5)


def test_uneven_sampling_and_shuffled_samples_with_times():
    rng = np.random.default_rng(0)
    positions, quaternions = jitter(*door(n=400), 0)
    keep = np.sort(rng.choice(400, 150, replace=False))  # dropped samples, gaps of varying length
    positions, quaternions = positions[keep], quaternions[keep]
    times = keep / HZ
    ordered = fit_trajectory(positions, quaternions)
    shuffle = rng.permutation(len(times))
    shuffled = fit_trajectory(positions[shuffle], quaternions[shuffle], times=times[shuffle])
    check(ordered, JointType.REVOLUTE, [0, 0, 1], 2.0)
    np.testing.assert_allclose(shuffled.direction, ordered.direction)
    assert isinstance(fit_trajectory(positions, times=times[:3]), NoAxis)


def test_a_stretch_without_samples_leaves_a_line_undecided():
    line = drawer(n=100)[0]
    line = line[np.r_[0:20, 80:100]]
    result = fit_trajectory(line)
    assert isinstance(result, NoAxis) and "no samples" in result.reason and result.details["bend_coverage"] < 0.5
    assert fit_trajectory(line, drawer(n=40)[1]).joint_type is JointType.PRISMATIC  # orientations: no turn


def test_a_gap_between_two_long_stretches_hides_nothing():
    """A third of the travel without samples, but a long stretch on each side: they would show a hinge's bend."""
    for seed in range(3):
        positions, _ = jitter(*drawer(seed=seed), seed)
        along = np.linspace(0, 1, len(positions))
        kept = (along < 0.35) | (along > 0.65)
        check(fit_trajectory(positions[kept]), JointType.PRISMATIC, [-1.0, 0.2, 0.0], 1.0)


def test_a_swing_with_most_of_it_lost_says_how_unsure_it_is():
    """70 % of a door's swing without samples, positions only: undecided, or a hinge whose reported sigma
    is many times the whole swing's and covers its error."""
    for seed in range(4):
        positions, _ = jitter(*door(arc_deg=70, seed=seed), seed)
        whole = fit_trajectory(positions)
        check(whole, JointType.REVOLUTE, [0, 0, 1], 1.0)
        along = np.linspace(0, 1, len(positions))
        result = fit_trajectory(positions[(along < 0.15) | (along > 0.85)])
        if isinstance(result, NoAxis):
            assert result.details["undecided"]
            continue
        error = axis_angle_error_deg([0, 0, 1], result.direction)
        assert result.joint_type is JointType.REVOLUTE and error <= 2 * result.direction_sigma_deg
        assert result.direction_sigma_deg >= 5 * whole.direction_sigma_deg


def test_one_bad_first_orientation_does_not_lean_the_hinge():
    """The gripper's turn is measured from the start all readings agree on, not from the first reading: a
    first orientation 2 deg off used to lean the hinge by 2-3 deg while reporting 1.3-1.6 deg of sigma."""
    for seed in range(3):
        positions, quaternions = door(arc_deg=40, seed=seed)
        rng = np.random.default_rng(seed)
        turns = np.radians(0.1) * rng.normal(size=(len(positions), 3))
        turns[0] = np.radians(2.0) * unit([1.0, 0.3, 0.0])
        quaternions = (Rotation.from_rotvec(turns) * Rotation.from_quat(quaternions)).as_quat()
        check(fit_trajectory(positions + rng.normal(0, 2e-3, positions.shape), quaternions), JointType.REVOLUTE,
              [0, 0, 1], 0.3)


def test_a_hinge_too_uncertain_to_trust_is_undecided_unless_the_joint_is_given():
    """A short, noisy arc from positions alone: the circle beats the line, but the hinge's direction is
    uncertain by more than MAX_HINGE_SIGMA_DEG."""
    for seed in range(3):
        positions, _ = door(arc_deg=28, radius_m=0.2, n=40)
        positions = positions + np.random.default_rng(seed).normal(0, 2.5e-3, positions.shape)
        result = fit_trajectory(positions)
        assert isinstance(result, NoAxis) and "uncertain by" in result.reason
        assert result.details["direction_sigma_deg"] > MAX_HINGE_SIGMA_DEG and result.details["arc_deg"] > 25
        given = fit_trajectory(positions, joint=JointType.REVOLUTE)
        assert given.joint_type is JointType.REVOLUTE and given.direction_sigma_deg > MAX_HINGE_SIGMA_DEG


def test_the_report_carries_the_noise_the_confidence_and_an_undecided_answers_details():
    positions, quaternions = jitter(*door(), 0, sensor_m=1e-3, tremor_m=0.0)
    report = fit_trajectory_report(positions, quaternions)
    assert report["joint_type"] == "revolute" and 0 < report["confidence"] <= 1 and report["direction_sigma_deg"] > 0
    assert report["noise_m"] == pytest.approx(1e-3, rel=0.3) and report["arc_deg"] == pytest.approx(60, abs=3)
    short = fit_trajectory_report(jitter(*drawer(travel_m=0.02, n=60), 0)[0])
    assert short["joint_type"] is None and "travel" in short["reason"] and short["details"]["undecided"]
    assert short["travel_m"] == pytest.approx(0.02, abs=0.005) and short["noise_m"] > 0


def test_a_turn_the_path_does_not_follow_is_undecided():
    """The gripper turned 30 deg with the travel, but the positions run straight: a slipping grasp."""
    positions, _ = jitter(*drawer(travel_m=0.25), 0)
    turning = door(arc_deg=30, n=len(positions))[1]
    result = fit_trajectory(positions, turning)
    assert isinstance(result, NoAxis) and "does not bend" in result.reason


def test_the_recorded_like_sets_meet_the_targets_on_draws_not_tuned_on():
    """5 draws of 60 paths of 12 objects (deploy.synthetic.handle_paths; the estimator was tuned on draws
    0-4): joint type right in >= 95 % of each draw, at most 1 wrong type in all, the error within 2 reported
    sigmas in >= 85 %, every object's median direction error <= 3 deg but one (seed 6's flap-1: positions
    only, the part's play along the hinge leans the plane of its path; 3.8 deg), none over 5 deg."""
    draws = [bench_axis_paths(seed=seed, given=False) for seed in range(5, 10)]
    assert all(d["paths"] == 60 and d["joint_type_accuracy"] >= 0.95 for d in draws)
    assert sum(d["wrong_type"] for d in draws) <= 1
    assert np.mean([d["within_2_sigma"] for d in draws]) >= 0.85
    medians = [m for d in draws for m in d["object_median_angle_deg"].values()]
    assert len(medians) == 60 and sum(m > 3.0 for m in medians) <= 1 and max(medians) <= 5.0
    assert {row["kind"] for row in draws[0]["rows"]} == {"drawer", "door", "flap", "slider"}


def test_handle_paths_are_reproducible_and_carry_the_truth():
    rng = np.random.default_rng(5)
    obj = random_object(rng, "door", "door-x")
    a, b = record_path(obj, np.random.default_rng(1)), record_path(obj, np.random.default_rng(1))
    np.testing.assert_array_equal(a.positions, b.positions)
    assert np.all(np.diff(a.times) > 0) and a.quaternions.shape == (len(a.times), 4)
    start = np.linalg.norm(np.cross(obj.axis.direction, obj.start - obj.axis.origin))
    assert 0.3 <= start <= 0.6
    paths = handle_path_set(1, objects_per_kind=(1, 1, 1, 1), paths_per_object=2)
    assert [p.kind for p in paths] == ["drawer"] * 2 + ["door"] * 2 + ["flap"] * 2 + ["slider"] * 2


def test_tum_and_csv_files_are_read():
    tum = "# timestamp tx ty tz qx qy qz qw\n2.0 0.1 0 0 0 0 0 1\n1.0 0 0 0 0 0 0 2\n"
    trajectory = parse_trajectory(tum)
    assert trajectory.format == "tum" and trajectory.times.tolist() == [2.0, 1.0]
    assert trajectory.quaternions[1].tolist() == [0, 0, 0, 1]
    csv = "time,Pos X [m],pos_y,pos_z,qw,qx,qy,qz\n0.0,1,2,3,1,0,0,0\n0.1,4,5,6,0,0,0,1\n"
    trajectory = parse_trajectory(csv)
    assert trajectory.format == "csv" and trajectory.positions.tolist() == [[1, 2, 3], [4, 5, 6]]
    assert trajectory.quaternions.tolist() == [[0, 0, 0, 1], [0, 0, 1, 0]] and trajectory.times[1] == 0.1
    assert parse_trajectory("x;y;z\n1;2;3\n").positions.tolist() == [[1, 2, 3]]
    with pytest.raises(ValueError, match="line 1: header a, b, c names no position columns"):
        parse_trajectory("a,b,c\n1,2,3\n")
    with pytest.raises(ValueError, match="line 3: 2 values but the header has 3"):
        parse_trajectory("x,y,z\n1,2,3\n1,2\n")
    with pytest.raises(ValueError, match="line 2: zero quaternion"):
        parse_trajectory("x y z qx qy qz qw\n1 2 3 0 0 0 0\n")
