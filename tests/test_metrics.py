"""Axis errors: angle between lines, distance near the object."""

import numpy as np
import pytest

from deploy.geometry.metrics import axis_angle_error_deg, axis_position_error_m


@pytest.mark.parametrize(
    ("a", "b", "expected"),
    [
        ([0, 0, 1], [0, 0, 2], 0.0),
        ([0, 0, 1], [0, 0, -1], 0.0),  # a line has no sign
        ([1, 0, 0], [0, 1, 0], 90.0),
        ([1, 0, 0], [np.cos(np.radians(30)), np.sin(np.radians(30)), 0], 30.0),
        ([1, 0, 0], [-np.cos(np.radians(30)), np.sin(np.radians(30)), 0], 30.0),
        ([1, 0, 0], [np.cos(1e-7), np.sin(1e-7), 0], np.degrees(1e-7)),  # accurate near zero
    ],
)
def test_angle_between_lines(a, b, expected):
    assert axis_angle_error_deg(np.array(a, float), np.array(b, float)) == pytest.approx(expected, abs=1e-12)


def test_position_error():
    z = np.array([0.0, 0.0, 1.0])
    # parallel lines 3 cm apart
    assert axis_position_error_m([0, 0, 0], z, [0.03, 0, 5], -z) == pytest.approx(0.03)
    # the same line described from another origin and direction sign
    assert axis_position_error_m([1, 2, 0], z, [1, 2, 7], -z) == pytest.approx(0.0, abs=1e-12)
    # crossing lines: zero at the crossing, growing away from it
    tilted = np.array([np.sin(0.1), 0.0, np.cos(0.1)])
    assert axis_position_error_m([0, 0, 0], z, [0, 0, 0], tilted) == pytest.approx(0.0, abs=1e-12)
    error = axis_position_error_m([0, 0, 0], z, [0, 0, 0], tilted, at=[0.5, 0.3, 1.0])
    assert error == pytest.approx(np.sin(0.1))


def test_degenerate_directions_raise():
    with pytest.raises(ValueError, match="d_est"):
        axis_angle_error_deg(np.array([0, 0, 1.0]), np.zeros(3))
    with pytest.raises(ValueError, match="dir_true"):
        axis_position_error_m(np.zeros(3), np.array([np.nan, 0, 1]), np.zeros(3), np.array([0, 0, 1.0]))
