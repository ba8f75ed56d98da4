"""The episode's eyes: frames grabbed during motions (every 1/camera_hz of arm time), then, between motions,
segmented and fed to the axis pipeline; the first frame fixes the body box."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from deploy.axis_pipeline import AxisPipeline, frame_points
from deploy.config import Config
from deploy.control.run_folder import RunFolder
from deploy.control.state import EpisodeStop, StopReason
from deploy.control.viewer import RerunViewer
from deploy.geometry.types import AxisResult, JointType, NoAxis
from deploy.perception.base import Segmenter
from drivers.arm.base import ArmState
from drivers.arm.kinematics import Kinematics
from drivers.camera.base import Camera, Frame


class Observer:
    """Grabs, segments and estimates. `vision` is the pipeline's latest estimate, `last_seen` the latest
    processed frame with its mask, `first_points` the first frame's object cloud (base frame, m)."""

    def __init__(self, camera: Camera, segmenter: Segmenter, kin: Kinematics, config: Config,
                 joint: JointType | None, t0: float = 0.0, folder: RunFolder | None = None,
                 viewer: RerunViewer | None = None) -> None:
        self.camera, self.segmenter, self.kin, self.config = camera, segmenter, kin, config
        self.folder, self.viewer = folder, viewer
        estimator = "paper-obb" if config.opening.policy == "paper" else config.estimator.name
        self.pipeline = AxisPipeline(config.replace(estimator={
            "name": estimator, "joint": "auto" if joint is None else joint.value}))
        self.first_frame: Frame | None = None
        self.first_points = np.zeros((0, 3))
        self.last_seen: tuple[Frame, np.ndarray] | None = None
        self.mask_pixels = 0
        self.vision: AxisResult = NoAxis("no frames yet")
        self.pending: list[tuple[Frame, ArmState]] = []
        self.next_frame_t = 0.0
        self.t0 = t0  # arm-clock start of the episode (viewer timeline)
        self.seconds = 0.0  # spent segmenting and estimating

    def first(self, arm_state: Callable[[], ArmState]) -> tuple[Frame, np.ndarray]:
        """Read and segment the first frame (the arm's state read after it), fix the body box; the frame and
        its object mask."""
        frame = self.camera.read()
        state = arm_state()
        self.first_frame = frame
        mask = self.segmenter.start(frame, self.config.perception.object_prompt)
        self.mask_pixels = int(np.count_nonzero(mask))
        if self.mask_pixels == 0:
            raise EpisodeStop(StopReason.NO_OBJECT,
                              "the segmenter found no object on the first frame: point the camera at it")
        pose = self.kin.fk(state.q)
        self.pipeline.update_frame(frame, mask, pose)
        self._log(frame, mask, state)
        self.first_points = frame_points(frame, mask, self.pipeline.config)
        if self.viewer is not None:
            self.viewer.cloud(self.first_points)
        self.next_frame_t = state.t
        return frame, mask

    def capture(self, state: ArmState) -> None:
        """During a motion: grab a frame when its slot has come (frames are processed after the motion)."""
        if state.t + 1e-9 >= self.next_frame_t:
            self.pending.append((self.camera.read(), state))
            self.next_frame_t = state.t + 1.0 / self.config.opening.camera_hz

    def process(self) -> None:
        """Segment the frames grabbed during the last motion and feed them to the pipeline, in order."""
        clock = time.perf_counter()
        pending, self.pending = self.pending, []
        for frame, state in pending:
            mask = self.segmenter.track(frame)
            self._log(frame, mask, state)
            if np.count_nonzero(mask) < self.config.opening.min_mask_fraction * self.mask_pixels:
                raise EpisodeStop(StopReason.TRACKING_LOST, f"the object's mask shrank to {np.count_nonzero(mask)} "
                                  f"pixels of {self.mask_pixels} at frame {frame.index}: the object left the view "
                                  "or is occluded")
            pose = self.kin.fk(state.q)
            self.vision = self.pipeline.update_frame(frame, mask, pose).result
            self.last_seen = frame, mask
        self.seconds += time.perf_counter() - clock

    def look(self) -> tuple[Frame, np.ndarray]:
        """A fresh frame and its object cloud (base frame), outside any motion (re-grasp)."""
        frame = self.camera.read()
        return frame, frame_points(frame, self.segmenter.track(frame), self.pipeline.config)

    def _log(self, frame: Frame, mask: np.ndarray, state: ArmState) -> None:
        pose = self.kin.fk(state.q)
        if self.folder is not None:
            self.folder.write_frame(frame, mask, state.q, pose)
        if self.viewer is not None:
            self.viewer.frame(state.t - self.t0, frame, mask, pose)
