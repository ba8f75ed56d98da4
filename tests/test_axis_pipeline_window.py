"""AxisPipeline: pauses of the held handle stay out of the estimator's window, and the body box's front can be the
face toward the robot rather than the camera."""

import numpy as np

from deploy.axis_pipeline import PAUSE_M, AxisPipeline
from deploy.config import Config


def grid(x, y, z) -> np.ndarray:
    return np.stack(np.meshgrid(x, y, z, indexing="ij"), axis=-1).reshape(-1, 3)


def cabinet() -> np.ndarray:
    """A cabinet's front (x = 0, 0.6 m wide) and its side (y = 0.3, 0.4 m deep), 1 m tall, at 5 mm spacing."""
    front = grid([0.0], np.arange(-0.3, 0.3, 0.005), np.arange(0.0, 1.0, 0.005))
    side = grid(np.arange(-0.4, 0.0, 0.005), [0.3], np.arange(0.0, 1.0, 0.005))
    return np.vstack([front, side])


def gripper(x: float) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, 3] = [x, 0.1, 0.5]
    return pose


def test_a_pause_takes_the_newest_frames_place_and_keeps_the_motion_in_the_window():
    """Frames in which the gripper moved less than PAUSE_M since the last frame that joined replace the newest one;
    a slow creep that adds up to PAUSE_M joins."""
    config = Config().replace(geometry={"moving_part": "box"}, estimator={"window": 4})
    pipe = AxisPipeline(config)
    camera = np.array([1.5, 0.0, 0.8])
    points = cabinet()
    pipe.update(points, 0, 0.0, camera)
    for index, x in enumerate([0.02, 0.04, 0.06], start=1):  # moving: each frame joins
        pipe.update(points + [x, 0, 0], index, index / 10, camera, gripper(x))
    for index in range(4, 10):  # held still: each frame takes the newest place, the older frames stay
        pipe.update(points + [0.06, 0, 0], index, index / 10, camera, gripper(0.06 + 1e-4 * (index - 3)))
    assert [o.index for o in pipe.window] == [1, 2, 9]
    for index, k in enumerate(range(1, 5), start=10):  # a creep of 0.6 PAUSE_M a frame from frame 3's pose
        x = 0.06 + k * 0.6 * PAUSE_M
        pipe.update(points + [x, 0, 0], index, index / 10, camera, gripper(x))
    assert [o.index for o in pipe.window] == [2, 10, 12, 13]  # 11 and 13 joined, 1.2 PAUSE_M from the last


def test_frames_without_a_gripper_pose_always_join():
    config = Config().replace(geometry={"moving_part": "box"}, estimator={"window": 4})
    pipe = AxisPipeline(config)
    camera = np.array([1.5, 0.0, 0.8])
    pipe.update(cabinet(), 0, 0.0, camera)
    for index in range(1, 6):
        pipe.update(cabinet(), index, index / 10, camera)
    assert [o.index for o in pipe.window] == [2, 3, 4, 5]


def test_the_front_faces_the_point_given_instead_of_the_camera():
    """A camera off to the side sees the cabinet's side best; `toward` (the robot's base) gives the real front."""
    config = Config().replace(geometry={"moving_part": "box"})
    camera = np.array([0.3, 1.6, 1.2])
    beside = AxisPipeline(config)
    beside.update(cabinet(), 0, 0.0, camera)
    facing = AxisPipeline(config, toward=np.array([1.2, 0.0, 0.0]))
    facing.update(cabinet(), 0, 0.0, camera)
    np.testing.assert_allclose(beside.front, [0, 1, 0], atol=1e-3)
    np.testing.assert_allclose(facing.front, [1, 0, 0], atol=1e-3)
