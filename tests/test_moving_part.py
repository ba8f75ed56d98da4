"""The moving part: points outside the grown body box, filtered again."""

import numpy as np
import pytest

from deploy.geometry.boxes import yaw_box
from deploy.geometry.moving_part import moving_part
from deploy.geometry.radius_filter import radius_filter
from deploy.geometry.types import Box


def grid(x, y, z) -> np.ndarray:
    return np.stack(np.meshgrid(x, y, z), axis=-1).reshape(-1, 3)


@pytest.fixture
def scene():
    """A closed cabinet's front face (x = 0) and a drawer front pulled 5 cm out (x = -0.05)."""
    cabinet = grid([0.0], np.arange(0.0, 0.5, 0.005), np.arange(0.0, 0.6, 0.005))
    drawer = grid([-0.05], np.arange(0.1, 0.4, 0.005), np.arange(0.3, 0.45, 0.005))
    box = yaw_box(np.concatenate([cabinet, grid([0.4], [0.0, 0.495], [0.0, 0.595])]))  # 0.4 deep body
    return cabinet, drawer, box


def test_moving_part_is_what_left_the_body_box(scene):
    cabinet, drawer, box = scene
    lone = np.array([[-0.3, 0.2, 0.2]])
    grazing = drawer + [0.045, 0, 0]  # 5 mm in front of the face: inside the 1 cm margin
    moving = moving_part(np.concatenate([cabinet, drawer, lone, grazing]), box, radius_m=0.02, eps=5)
    assert {tuple(p) for p in moving} == {tuple(p) for p in drawer}
    # with a 1 mm margin the grazing points count as outside (and have neighbours): they are kept
    everything = np.concatenate([cabinet, drawer, lone, grazing])
    moving = moving_part(everything, box, margin_m=0.001, radius_m=0.02, eps=5)
    assert len(moving) == len(drawer) + len(grazing)


def test_default_filter_is_the_papers_sim_profile(scene):
    cabinet, drawer, box = scene
    sparse = drawer[::40]  # too few neighbours within 5 cm for eps = 100
    moving = moving_part(np.concatenate([cabinet, drawer]), box)
    assert np.array_equal(moving, radius_filter(drawer, 0.05, 100))
    assert 0.95 * len(drawer) < len(moving) < len(drawer)  # only the drawer's corners are thinned
    assert len(moving_part(np.concatenate([cabinet, sparse]), box)) == 0
    assert len(moving_part(np.concatenate([cabinet, sparse]), box, radius_m=0.05, eps=3)) == len(sparse)


def test_empty_and_non_finite_input(scene):
    _, drawer, box = scene
    assert moving_part(np.zeros((0, 3)), box).shape == (0, 3)
    with_nan = np.concatenate([drawer, [[np.nan, 0.2, 0.3]]])
    assert np.all(np.isfinite(moving_part(with_nan, box, radius_m=0.02, eps=5)))


def test_body_box_rotation_is_used():
    quarter_turn = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    box = Box(np.zeros(3), quarter_turn, np.array([1.0, 0.2, 0.2]))
    inside_rotated = grid([0.0], np.arange(-0.4, 0.4, 0.01), [0.0])  # along the box's long axis (world y)
    outside_rotated = grid(np.arange(0.2, 0.4, 0.01), [0.0], [0.0])  # along world x, beyond 0.1 + margin
    moving = moving_part(np.concatenate([inside_rotated, outside_rotated]), box, radius_m=0.02, eps=1)
    assert {tuple(p) for p in moving} == {tuple(p) for p in outside_rotated}


def front_and_inside() -> tuple[np.ndarray, np.ndarray]:
    """A cabinet's front (x = 0, all the first frame sees) and its inside 30 cm behind it."""
    rng = np.random.default_rng(0)
    front = np.c_[np.zeros(4000), rng.uniform(-0.3, 0.3, 4000), rng.uniform(0.0, 0.6, 4000)]
    inside = np.c_[np.full(6000, -0.3), rng.uniform(-0.25, 0.25, 6000), rng.uniform(0.05, 0.55, 6000)]
    return front, inside


@pytest.mark.parametrize("joint, inside_depth_m, interior_counts",
                         [("revolute", 1.0, False), ("revolute", 0.0, True), ("prismatic", 1.0, True)])
def test_the_cabinets_inside_revealed_by_a_door_is_not_the_moving_part(joint, inside_depth_m, interior_counts):
    """The box cut: the first frame sees only the front (a thin body box); opening reveals the inside 30 cm behind
    it: static behind a door, the drawer itself behind a drawer's front."""
    from deploy.axis_pipeline import AxisPipeline
    from deploy.config import Config

    front, inside = front_and_inside()
    config = Config().model_copy(update={
        "geometry": Config().geometry.model_copy(update={"inside_depth_m": inside_depth_m, "moving_part": "box"}),
        "estimator": Config().estimator.model_copy(update={"joint": joint})})
    pipe = AxisPipeline(config)
    camera = np.array([1.5, 0.2, 0.8])
    pipe.update(front, 0, 0.0, camera)
    step = pipe.update(np.vstack([front, inside]), 1, 0.1, camera)
    assert (step.moving_points > 5000 if interior_counts else step.moving_points == 0)


def test_a_door_classified_after_the_first_frame_gets_the_deep_box():
    """The box cut: `--joint auto` sets the pipeline's joint once the probe pull has classified it."""
    from deploy.axis_pipeline import AxisPipeline
    from deploy.config import Config
    from deploy.geometry.types import JointType

    front, inside = front_and_inside()
    pipe = AxisPipeline(Config().replace(geometry={"moving_part": "box"}))
    camera = np.array([1.5, 0.2, 0.8])
    pipe.update(front, 0, 0.0, camera)
    assert pipe.update(np.vstack([front, inside]), 1, 0.1, camera).moving_points > 5000
    pipe.joint = JointType.REVOLUTE
    assert pipe.update(np.vstack([front, inside]), 2, 0.2, camera).moving_points == 0
