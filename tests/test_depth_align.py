"""Depth aligned to colour without rounding holes: software-device recordings (pyrealsense2) converted to frames
directories, checked pixel by pixel against the scene ray-cast from the colour camera."""

import numpy as np
import pytest
from realsense_recordings import Synthetic, expected_depth, scene, write_db3

from drivers.camera.base import Intrinsics
from drivers.camera.depth_align import DepthAligner
from drivers.camera.frames_dir import FramesRecording
from drivers.camera.realsense_convert import convert_recording


def converted(tmp_path, s: Synthetic, name: str) -> np.ndarray:
    out = tmp_path / name
    convert_recording(write_db3(tmp_path / f"{name}.db3", s), out)
    return FramesRecording(out).frame(0).depth_m


def test_coregistered_streams_keep_every_depth_pixel(tmp_path):
    s = scene(2, depth_fx=50.0, color_fx=50.0, baseline_m=0.0)
    depth = converted(tmp_path, s, "coregistered")
    assert not (depth == 0).any()  # librealsense's rs.align left 5 % holes here (columns 2 and 5, a row)
    np.testing.assert_array_equal(np.round(depth / 0.001), np.round(s.depth[0] * s.depth_units_m / 0.001))


@pytest.mark.parametrize("geometry", [
    dict(width=96, height=72, depth_fx=50.0, color_fx=50.0, baseline_m=0.1),  # wide baseline: occlusion band
    dict(),  # the D415-like default: depth fx 60, colour fx 50, 15 mm baseline
])
def test_only_the_holes_the_reprojection_uncovers(tmp_path, geometry):
    s = scene(2, **geometry)
    depth = converted(tmp_path, s, "baseline")
    expected = expected_depth(s)
    np.testing.assert_allclose(depth, expected, atol=1e-3)
    band = (expected == 0) & (np.roll(expected, -1, axis=1) == 0.8)  # uncovered beside the square's edge
    assert band.any() == (geometry.get("baseline_m", 0.0) > 0.05)


def test_a_slanted_surface_has_no_seams():
    width, height, fx = 80, 60, 55.0
    intr = Intrinsics(width, height, fx, fx, (width - 1) / 2, (height - 1) / 2)
    cols = np.arange(width, dtype=float)
    depth = np.tile(1.3 - 0.6 * cols / width, (height, 1)).astype(np.float32)  # 1.3 .. 0.7 m: footprints part
    aligner = DepthAligner(intr, intr, np.eye(3), [0.04, 0.01, 0.0])
    aligned = aligner.align(depth)
    covered = aligned[1:, 4:] > 0  # the rows and columns the shifted depth field of view covers
    assert covered.all()
    assert DepthAligner(intr, intr, np.eye(3), [0.0, 0.0, 0.0]).coregistered
    np.testing.assert_array_equal(DepthAligner(intr, intr, np.eye(3), [0.0, 0.0, 0.0]).align(depth), depth)


def test_a_hole_in_the_depth_image_stays_a_hole():
    intr = Intrinsics(40, 30, 40.0, 40.0, 19.5, 14.5)
    depth = np.full((30, 40), 1.0, np.float32)
    depth[10:20, 20] = 0.0  # one missing depth column: not a seam of the re-projection
    aligned = DepthAligner(intr, intr, np.eye(3), [0.02, 0.0, 0.0]).align(depth)
    assert (aligned[10:20] == 0).sum(axis=1).min() >= 1
    assert (aligned[:10, 2:-2] > 0).all()
