"""Following the object against the first frame's static scene (deploy/geometry/static_scene.py).

The object's mask on a later frame is the first frame's furniture pixels that still show its static surfaces, plus
the moving part: what stands in front of the static scene inside the opening region. Nothing is followed from frame
to frame, so nothing can drift: an arm passing in front hides pixels (the self-filter removed their depth: unknown,
in neither set) and they come back when it has passed; a neighbour's front, however alike, never stands in front of
the static scene, so it never enters. The camera must stay where it was (a tripod or the robot's base).
"""

from __future__ import annotations

import cv2
import numpy as np

from deploy.errors import PerceptionError
from deploy.geometry.boxes import front_box, front_direction
from deploy.geometry.cloud import depth_to_points
from deploy.geometry.static_scene import (
    StaticScene,
    left_static,
    moving_pixels,
    opening_reach_m,
    opening_region,
    static_scene,
)
from deploy.geometry.types import Box
from deploy.perception.base import Segmenter
from drivers.camera.base import Frame

TRACK_STEP = 2  # every 2nd pixel in each direction (the axis pipeline's decimation)


def front_region(frame: Frame, front_mask: np.ndarray, reach_m: float) -> Box:
    """The opening region of the front (or whole furniture) whose pixels are `front_mask` in `frame`: its front box
    (base frame), swept out to `reach_m` or its width if larger. PerceptionError when the frame has no pose or the
    mask no depth."""
    if frame.T_base_camera is None:
        raise PerceptionError(f"frame {frame.index} has no camera pose: the opening region is set in the arm's base "
                              "frame; calibrate (`deploy calibrate hand-eye`) or give --calibration")
    points = depth_to_points(frame.depth_m, frame.intrinsics.K, mask=front_mask, T_base_camera=frame.T_base_camera)
    if len(points) < 4:
        raise PerceptionError(f"the front's mask on frame {frame.index} has {len(points)} pixels with depth: no "
                              "opening region; point at the part again, where the camera sees it")
    view = np.asarray(frame.T_base_camera)[:3, 3]
    box = front_box(points, view)
    outward = front_direction(box, view)
    return opening_region(box, outward, opening_reach_m(box, outward, reach_m))


class StaticSceneTracker:
    """The object's mask on later frames of a fixed camera: `track(frame)` (see the module docstring). `moving` is
    the last frame's moving part (every TRACK_STEP-th pixel)."""

    def __init__(self, first: Frame, furniture: np.ndarray, region: Box) -> None:
        self.scene: StaticScene = static_scene(first.depth_m, first.intrinsics.K, TRACK_STEP, first.T_base_camera)
        self.furniture = np.asarray(furniture, bool)[::TRACK_STEP, ::TRACK_STEP]
        self.region = region
        self.moving = np.zeros(self.furniture.shape, bool)

    def track(self, frame: Frame) -> np.ndarray:
        """The object's (H, W) mask on `frame` (its arm's depth already removed); PerceptionError when the camera
        moved since the first frame."""
        self.scene.check_view(frame.depth_m, frame.T_base_camera)
        self.moving, _ = moving_pixels(self.scene, frame.depth_m, self.region)
        depth = frame.depth_m[::TRACK_STEP, ::TRACK_STEP]
        static = self.furniture & (depth > 0) & ~left_static(self.scene, frame.depth_m)
        h, w = frame.depth_m.shape
        small = (static | self.moving).astype(np.uint8)
        full = cv2.resize(small, (small.shape[1] * TRACK_STEP, small.shape[0] * TRACK_STEP),
                          interpolation=cv2.INTER_NEAREST)[:h, :w]
        return full.astype(bool) & (frame.depth_m > 0)


class StaticSceneSegmenter(Segmenter):
    """A segmenter that finds the object with `finder` on the first frame and follows it with a `StaticSceneTracker`.

    region: the opening region (e.g. of the front the user pointed at); None: the first mask's, reaching
    `reach_m` (or its width) out of its front.
    """

    name = "static-scene"

    def __init__(self, finder: Segmenter, region: Box | None = None, reach_m: float = 0.6) -> None:
        self.finder, self.region, self.reach_m = finder, region, reach_m
        self.tracker: StaticSceneTracker | None = None

    def start(self, frame: Frame, prompt: str = "cabinet") -> np.ndarray:
        mask = self.finder.start(frame, prompt)
        region = self.region if self.region is not None else front_region(frame, mask, self.reach_m)
        self.tracker = StaticSceneTracker(frame, mask, region)
        return mask

    def track(self, frame: Frame) -> np.ndarray:
        if self.tracker is None:
            raise PerceptionError("static-scene: track() called before start(); call start on the first frame")
        return self.tracker.track(frame)

    def handle_mask(self, frame: Frame) -> np.ndarray | None:
        return self.finder.handle_mask(frame)
