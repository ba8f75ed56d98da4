"""Synthetic RGB-D sequences of a cabinet opening, with ground truth, and their frames recordings."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from deploy.geometry.types import Axis, Box
from deploy.synthetic.cabinet import Kind, SyntheticCabinet
from deploy.synthetic.raycast import render_rgbd
from drivers.camera.base import Frame, Intrinsics, SegLabel
from drivers.camera.depth_noise import DepthNoise
from drivers.camera.frames_dir import FramesWriter

D415_640X480 = Intrinsics(640, 480, 615.0, 615.0, 319.5, 239.5)
"""Typical D415 colour intrinsics at 640x480 (depth aligned to colour)."""


@dataclass(frozen=True)
class Viewpoint:
    """Ranges (uniform) of the tripod camera: angle off the front normal and elevation of that offset
    above the horizontal side direction (deg; negative = below the cabinet's centre), and distance (m)
    from the front."""

    off_normal_deg: tuple[float, float] = (15.0, 35.0)
    lift_deg: tuple[float, float] = (30.0, 70.0)
    distance_m: tuple[float, float] = (0.6, 0.9)
    min_height_m: float = 0.0


STANDARD_VIEW = Viewpoint()
"""Above the cabinet and to one side: little of a drawer's side walls shows."""
VARIED_VIEW = Viewpoint(off_normal_deg=(0.0, 60.0), lift_deg=(-20.0, 70.0), distance_m=(0.5, 1.3),
                        min_height_m=0.25)
"""Head-on to far to the side (a drawer's side wall in view), from below to well above, near to far."""


@dataclass(frozen=True)
class SyntheticSequence:
    """Frames of one opening (`mask` = object incl. handle, `segmentation` = labels) with ground truth.

    gripper_poses: 4x4 handle grasp pose per frame (base frame), as a robot holding the handle would
    sense it; joint_values: q per frame (m or rad).
    """

    frames: list[Frame]
    gripper_poses: list[np.ndarray]
    cabinet: SyntheticCabinet
    true_axis: Axis
    joint_values: np.ndarray
    T_base_camera: np.ndarray

    @property
    def kind(self) -> Kind:
        return self.cabinet.kind


def look_at(eye: np.ndarray, target: np.ndarray) -> np.ndarray:
    """4x4 OpenCV camera pose (x right, y down, z forward) at `eye` looking at `target`, z up."""
    forward = np.asarray(target, float) - eye
    right = np.cross(forward, [0.0, 0.0, 1.0])
    if np.linalg.norm(right) < 1e-9 * max(np.linalg.norm(forward), 1.0):
        raise ValueError(f"look_at: camera at {eye} looks straight up or down at {target}; roll undefined")
    forward /= np.linalg.norm(forward)
    right /= np.linalg.norm(right)
    T = np.eye(4)
    T[:3, :3] = np.column_stack([right, np.cross(forward, right), forward])
    T[:3, 3] = eye
    return T


def random_camera_pose(
    rng: np.random.Generator, cabinet: SyntheticCabinet, intrinsics: Intrinsics | None = None, margin_px: int = 16,
    view: Viewpoint = STANDARD_VIEW,
) -> np.ndarray:
    """A tripod camera `view.off_normal_deg` off the front normal, its offset lifted by `view.lift_deg`
    from the side direction (to one side, at random), aimed at the cabinet's centre, `view.distance_m`
    from the front, moved back until the whole cabinet is in view. A pose lower than
    `view.min_height_m` is drawn again."""
    intrinsics = D415_640X480 if intrinsics is None else intrinsics
    T = cabinet.T_base_cabinet
    normal = T[:3, 0]
    target = T[:3, :3] @ np.array([-cabinet.depth_m / 2, 0.0, cabinet.height_m / 2]) + T[:3, 3]
    front = target + cabinet.depth_m / 2 * normal
    corners = np.vstack([box.corners() for box, _ in cabinet.body_parts()])
    while True:
        side = np.cross([0.0, 0.0, 1.0], normal) * rng.choice([-1.0, 1.0])
        off_normal, lift = np.radians(rng.uniform(*view.off_normal_deg)), np.radians(rng.uniform(*view.lift_deg))
        direction = math.cos(off_normal) * normal + math.sin(off_normal) * (
            math.cos(lift) * side + math.sin(lift) * np.array([0.0, 0.0, 1.0])
        )
        pose = _framing_pose(front, target, direction, rng.uniform(*view.distance_m), corners,
                             intrinsics, margin_px)
        if pose[2, 3] >= view.min_height_m:
            return pose


def _framing_pose(front, target, direction, distance, corners, intrinsics, margin_px) -> np.ndarray:
    """The camera at `front + distance * direction` looking at `target`, moved back in 5 cm steps until
    every corner projects `margin_px` inside the image (or 3 m away)."""
    while True:
        pose = look_at(front + distance * direction, target)
        cam = (corners - pose[:3, 3]) @ pose[:3, :3]
        u = intrinsics.fx * cam[:, 0] / cam[:, 2] + intrinsics.cx
        v = intrinsics.fy * cam[:, 1] / cam[:, 2] + intrinsics.cy
        inside = (u >= margin_px) & (u <= intrinsics.width - margin_px) & (v >= margin_px)
        if np.all(cam[:, 2] > 0) and np.all(inside & (v <= intrinsics.height - margin_px)) or distance > 3.0:
            return pose
        distance += 0.05


def _scene_background(cabinet: SyntheticCabinet) -> list[tuple[Box, SegLabel]]:
    """The floor (z = 0) and, for a raised cabinet, a table under it."""
    boxes = [(Box(np.array([0.0, 0.0, -0.01]), np.eye(3), np.array([6.0, 6.0, 0.02])), SegLabel.BACKGROUND)]
    top = cabinet.position[2]
    if top > 0:
        T = cabinet.T_base_cabinet
        center = T[:3, 3] + T[:3, :3] @ np.array([-cabinet.depth_m / 2, 0.0, -top / 2])
        extent = np.array([cabinet.depth_m + 0.3, cabinet.width_m + 0.4, top])
        boxes.append((Box(center, T[:3, :3].copy(), extent), SegLabel.BACKGROUND))
    return boxes


def synthetic_sequence(
    kind: Kind,
    rng: np.random.Generator,
    travel: float,
    n_frames: int,
    noise: DepthNoise | None = None,
    intrinsics: Intrinsics = D415_640X480,
    fps: float = 10.0,
    gripper_noise_m: float = 0.0,
    cabinet: SyntheticCabinet | None = None,
    gripper_noise_deg: float = 0.0,
    view: Viewpoint = STANDARD_VIEW,
    easing: bool = False,
) -> SyntheticSequence:
    """Render a cabinet (random unless given) opening from q = 0 to `travel` (m or rad) in `n_frames`
    steps, even or, with `easing`, slow at both ends (smoothstep), seen by a random tripod camera
    (`view`), with `noise` (default `DepthNoise.d415()`) on the depth, Gaussian noise of
    `gripper_noise_m` on the gripper positions and rotations of `gripper_noise_deg` (per axis,
    standard deviation) on their orientations."""
    if n_frames < 1:
        raise ValueError(f"n_frames must be at least 1, got {n_frames}")
    noise = DepthNoise.d415() if noise is None else noise
    cabinet = SyntheticCabinet.random(rng, kind) if cabinet is None else cabinet
    T_base_camera = random_camera_pose(rng, cabinet, intrinsics, view=view)
    background = _scene_background(cabinet)
    joint_values = np.linspace(0.0, travel, n_frames)
    if easing:
        joint_values = travel * (3 * (joint_values / travel) ** 2 - 2 * (joint_values / travel) ** 3)
    frames, poses = [], []
    for i, q in enumerate(joint_values):
        color, depth, labels = render_rgbd(background + cabinet.parts(q), intrinsics, T_base_camera)
        frames.append(
            Frame(
                index=i,
                t=i / fps,
                color=color,
                depth_m=noise.apply(depth, intrinsics.fx, rng),
                intrinsics=intrinsics,
                T_base_camera=T_base_camera.copy(),
                segmentation=labels,
                mask=(labels == SegLabel.OBJECT) | (labels == SegLabel.HANDLE),
            )
        )
        pose = cabinet.handle_pose(q)
        if gripper_noise_m > 0:
            pose[:3, 3] += rng.normal(0.0, gripper_noise_m, 3)
        if gripper_noise_deg > 0:
            rotvec = np.radians(rng.normal(0.0, gripper_noise_deg, 3))
            pose[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix() @ pose[:3, :3]
        poses.append(pose)
    return SyntheticSequence(frames, poses, cabinet, cabinet.true_axis(), joint_values, T_base_camera)


def write_sequence(seq: SyntheticSequence, path: str | Path) -> None:
    """Write `seq` as a frames recording (masks, ee_pose = gripper pose, joint_positions = [q]) plus
    truth.json {"joint_type", "origin", "direction", "joint_values"}."""
    frames = seq.frames
    if not frames:
        raise ValueError("cannot write an empty sequence")
    with FramesWriter(path, frames[0].intrinsics, T_base_camera=seq.T_base_camera) as writer:
        for frame, pose, q in zip(frames, seq.gripper_poses, seq.joint_values, strict=True):
            writer.write(frame, mask=frame.mask, joint_positions=[q], ee_pose=pose)
    truth = {
        "joint_type": seq.true_axis.joint_type.value,
        "origin": [float(v) for v in seq.true_axis.origin],
        "direction": [float(v) for v in seq.true_axis.direction],
        "joint_values": [float(q) for q in seq.joint_values],
    }
    (Path(path) / "truth.json").write_text(json.dumps(truth, indent=2) + "\n", encoding="utf-8")
