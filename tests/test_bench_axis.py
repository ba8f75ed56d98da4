"""`deploy bench axis`: the scene sets and the tail statistics (median, p90, max) of every estimator."""

import json
import re

import numpy as np
import pytest

from deploy.bench.axis import SequenceResult, make_sequences, summarise
from deploy.bench.axis_paths import summarise_paths
from deploy.cli import main


def result(kind, angle, reason="", confidence=None, sigma=None):
    return SequenceResult("screw", kind, angle, None if angle is None else 0.01, angle is not None, [1.0], [2.0],
                          reason, confidence, sigma)


def test_summary_has_median_p90_and_max_and_counts_failures_as_90_deg():
    rows = [result("drawer", a) for a in (0.1, 0.2, 0.3, 0.4, 5.0)] + [result("drawer", None, "too few points")]
    rows += [result("door", 1.0)]
    s = summarise(rows)["screw"]
    assert s["drawer_angle_deg_median"] == pytest.approx(0.35)
    assert s["drawer_angle_deg_max"] == 90.0 and s["drawer_angle_deg_p90"] == pytest.approx(47.5)
    assert s["failures"] == {"drawer: too few points": 1} and s["failed_estimates"] == 1


def test_summary_says_whether_the_estimator_knew_when_it_was_unsure():
    """Within 2 sigma over the estimates that report a sigma; median error of the less and the more
    confident half."""
    rows = [result("drawer", a, confidence=c, sigma=s)
            for a, c, s in ((0.1, 0.9, 0.2), (0.2, 0.8, 0.5), (3.0, 0.2, 1.0), (5.0, 0.1, None))]
    rows += [result("drawer", None, "no registration", confidence=None)]
    s = summarise(rows)["screw"]
    assert s["drawer_sigma_reported"] == 3 and s["drawer_within_2_sigma"] == pytest.approx(2 / 3)
    assert s["drawer_angle_deg_median_low_confidence"] == pytest.approx(4.0)
    assert s["drawer_angle_deg_median_high_confidence"] == pytest.approx(0.15)
    assert s["door_sigma_reported"] == 0 and s["door_within_2_sigma"] is None


def test_coverage_is_the_share_within_2_sigma_over_drawers_and_doors():
    rows = [result("drawer", 0.1, confidence=0.9, sigma=0.1), result("drawer", 0.5, confidence=0.9, sigma=0.2),
            result("door", 0.3, confidence=0.5, sigma=1.0), result("door", 2.0, confidence=0.5, sigma=None),
            result("door", None, "no registration")]
    s = summarise(rows)["screw"]
    assert s["coverage_estimates"] == 3 and s["coverage_2_sigma"] == pytest.approx(2 / 3)
    assert summarise([result("drawer", 1.0)])["screw"]["coverage_2_sigma"] is None


def test_bench_axis_table_shows_the_coverage(capsys):
    assert main(["bench", "axis", "--sequences", "1"]) == 0
    out = capsys.readouterr().out
    assert "2 sigma cover" in out and re.search(r"\d+ % of \d+", out) and "90-99 %" in out


def test_varied_scenes_are_short_eased_openings():
    seqs = make_sequences(2, 0, scenes="varied")
    assert [s.kind for s in seqs] == ["drawer", "door", "drawer", "door"]
    for seq in seqs:
        assert 6 <= len(seq.frames) <= 20
        steps = np.diff(seq.joint_values)
        assert steps[0] < steps[len(steps) // 2]  # slow start
    with pytest.raises(ValueError, match="unknown scene set"):
        make_sequences(1, 0, scenes="nope")


def test_path_summary_counts_undecided_apart_from_wrong():
    rows = [
        {"object": "door-0", "kind": "door", "type": "revolute", "right": True, "angle_deg": 1.0, "sigma_deg": 1.0,
         "given_angle_deg": 1.0, "reason": None, "ms": 1.0},
        {"object": "door-0", "kind": "door", "type": None, "right": False, "angle_deg": None, "sigma_deg": None,
         "given_angle_deg": 2.0, "reason": "joint type undecided: only 1.2 cm of travel", "ms": 1.0},
        {"object": "slider-0", "kind": "slider", "type": "revolute", "right": False, "angle_deg": 80.0,
         "sigma_deg": 5.0, "given_angle_deg": 1.0, "reason": None, "ms": 1.0},
    ]
    s = summarise_paths(rows)
    assert s["joint_type_accuracy"] == pytest.approx(1 / 3) and s["wrong_type"] == 1 and s["undecided"] == 1
    assert s["undecided_causes"] == {"only N cm of travel": 1}
    assert s["object_median_angle_deg"] == {"door-0": 1.0, "slider-0": 80.0}
    assert s["within_2_sigma"] == 1.0


def test_bench_axis_paths_cli_json(capsys):
    assert main(["bench", "axis", "--scenes", "paths", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    assert data["paths"] == 60 and set(data["kinds"]) == {"drawer", "door", "flap", "slider"}
    assert data["wrong_type"] == 0 and data["joint_type_accuracy"] >= 0.95
