"""The `rgbd` segmenter: finds and follows the object from colour + depth + the camera's pose, with no weights.

Detector (first frame, and again when the track collapses): the depth image as points in the robot's base frame
(the self-filter has already removed the arm), kept within the arm's reach; a floor or table top (a large
horizontal plane at the bottom of the view) is removed; what is left is clustered (DBSCAN) and the object is the
cluster that holds the point the user pointed at (the `Pointer`'s pixel seen in depth on the first frame), or
without a pointer the largest cluster of a piece of furniture's size. With `box` set only pixels inside it count.

Tracker: the object is the furniture that does not move plus the part that opens. Its region is the detected
object's box in the base frame, grown by `track_margin_m` and reaching `opening_reach_m` (or the front's width,
for a door) out of its front; a later frame's mask is what lies in that region and is connected in the image
to the previous mask. It follows the object through camera motion and partial occlusion.
"""

from __future__ import annotations

import logging

import cv2
import numpy as np
import open3d as o3d

from deploy.errors import PerceptionError
from deploy.geometry.boxes import front_box, front_direction
from deploy.geometry.cloud import depth_to_points, project
from deploy.geometry.types import Box
from deploy.perception.base import Pointer, Segmenter
from deploy.perception.classical import keep_touching
from deploy.perception.config import PerceptionConfig
from deploy.perception.track_health import track_lost
from drivers.camera.base import Frame

log = logging.getLogger(__name__)

DETECT_STEP = 4  # the detector looks at every 4th pixel in each direction
TRACK_STEP = 2  # the tracker at every 2nd (the axis pipeline's decimation)
CLUSTER_EPS_M = 0.06  # grazing faces (a cabinet side) are sampled sparsely
CLUSTER_MIN_POINTS = 10
MIN_OBJECT_SIZE_M, MAX_OBJECT_SIZE_M = 0.15, 2.5  # a cluster's largest horizontal or vertical extent
PLANE_TOLERANCE_M = 0.015
MIN_PLANE_SHARE = 0.1  # a floor holds at least this share of the points in reach
FLOOR_BAND_M = 0.05  # ... and lies within this of the lowest points
FLOOR_CLEARANCE_M = 0.02  # the tracking region starts this far above the object's bottom
POINT_WINDOW_PX = 7  # the pointed pixel's depth: the median of the depths measured within this many pixels of it
POINT_NEAR_M = 2 * CLUSTER_EPS_M  # the pointed object is the cluster with a point this near the pointed point


def pixel_points(frame: Frame, step: int, valid: np.ndarray | None = None,
                 rows: slice = slice(None), cols: slice = slice(None)) -> tuple[np.ndarray, np.ndarray]:
    """Base-frame points of every `step`-th pixel with depth (and `valid`), and their (row, col) indices in the
    reduced image; `rows` / `cols` (in the reduced image) limit the search."""
    depth = np.zeros(frame.depth_m[::step, ::step].shape)
    depth[rows, cols] = frame.depth_m[::step, ::step][rows, cols]
    keep = np.isfinite(depth) & (depth > 0)
    if valid is not None:
        keep &= valid[::step, ::step]
    K = np.diag([1.0 / step, 1.0 / step, 1.0]) @ frame.intrinsics.K
    points = depth_to_points(depth, K, mask=keep, T_base_camera=frame.T_base_camera, min_depth_m=0.0,
                             dist=frame.intrinsics.dist_coeffs)
    return points, np.argwhere(keep)


def remove_floor(points: np.ndarray) -> np.ndarray:
    """Bool keep-mask: False on a dominant horizontal plane at the bottom of the points (floor, table top)."""
    keep = np.ones(len(points), bool)
    if len(points) < 100:
        return keep
    o3d.utility.random.seed(0)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    plane, inliers = cloud.segment_plane(PLANE_TOLERANCE_M, 3, 200)
    a, b, c, _ = plane
    low = np.percentile(points[:, 2], 2)
    if abs(c) > 0.95 * np.linalg.norm([a, b, c]) and len(inliers) >= MIN_PLANE_SHARE * len(points) \
            and np.median(points[inliers, 2]) < low + FLOOR_BAND_M:
        keep[inliers] = False
        keep &= points[:, 2] > np.median(points[inliers, 2]) + PLANE_TOLERANCE_M
    return keep


def clusters(points: np.ndarray) -> np.ndarray:
    """DBSCAN cluster labels of `points` (-1: noise)."""
    if len(points) < CLUSTER_MIN_POINTS:
        return np.full(len(points), -1)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    return np.asarray(cloud.cluster_dbscan(CLUSTER_EPS_M, CLUSTER_MIN_POINTS))


def largest_object(points: np.ndarray) -> np.ndarray:
    """Indices of the largest cluster of a furniture-like size (empty when there is none)."""
    labels = clusters(points)
    best = np.zeros(0, int)
    for label in np.unique(labels[labels >= 0]):
        members = np.flatnonzero(labels == label)
        size = np.ptp(points[members], axis=0)
        if MIN_OBJECT_SIZE_M <= max(size.max(), 0.0) <= MAX_OBJECT_SIZE_M and len(members) > len(best):
            best = members
    return best


def pointed_object(points: np.ndarray, pointed: np.ndarray) -> np.ndarray:
    """Indices of the cluster holding the point nearest `pointed` (base frame, m), when that point is within
    POINT_NEAR_M of it (empty otherwise)."""
    if len(points) == 0:
        return np.zeros(0, int)
    labels = clusters(points)
    distance = np.linalg.norm(points - pointed, axis=1)
    distance[labels < 0] = np.inf
    nearest = int(np.argmin(distance))
    if distance[nearest] > POINT_NEAR_M:
        return np.zeros(0, int)
    return np.flatnonzero(labels == labels[nearest])


def pointed_point(frame: Frame, pointer: Pointer) -> np.ndarray:
    """The base-frame point (m) the pointer's pixel shows: its depth is the median of the depths measured within
    POINT_WINDOW_PX of it. PerceptionError when the pixel is off the image or nothing near it has depth."""
    h, w = frame.depth_m.shape
    if not pointer.inside(w, h):
        raise PerceptionError(f"the pointed pixel ({pointer.u:g}, {pointer.v:g}) is off the {w}x{h} image: point at "
                              "the part to open in the first frame")
    row, col = pointer.pixel()
    r0, c0 = max(row - POINT_WINDOW_PX, 0), max(col - POINT_WINDOW_PX, 0)
    window = frame.depth_m[r0:row + POINT_WINDOW_PX + 1, c0:col + POINT_WINDOW_PX + 1]
    measured = window[np.isfinite(window) & (window > 0)]
    if measured.size == 0:
        raise PerceptionError(f"no depth at the pointed pixel ({pointer.u:g}, {pointer.v:g}) on frame {frame.index}: "
                              "point at the part's front where the camera measures depth")
    K = frame.intrinsics
    z = float(np.median(measured))
    ray = np.array([(pointer.u - K.cx) / K.fx * z, (pointer.v - K.cy) / K.fy * z, z])
    T = np.asarray(frame.T_base_camera)
    return T[:3, :3] @ ray + T[:3, 3]


class RGBDSegmenter(Segmenter):
    """No-weights detector and 3D-region tracker (see the module docstring); frames must carry their pose."""

    name = "rgbd"

    def __init__(self, config: PerceptionConfig | None = None) -> None:
        self.config = config or PerceptionConfig()
        self.region: Box | None = None  # the object's box, base frame
        self._front = np.zeros(3)
        self._seed = np.zeros((0, 0), bool)  # the last detection's pixels
        self._good: np.ndarray | None = None
        self._reference_area = 0
        self._pointed: np.ndarray | None = None  # the point the user pointed at, base frame
        self.redetections = 0

    def start(self, frame: Frame, prompt: str | None = None, pointer: Pointer | None = None) -> np.ndarray:
        """The object on the first frame: the furniture holding what `pointer` shows, else the largest in reach
        (`prompt` is not used)."""
        self._require_pose(frame)
        self._pointed = None if pointer is None else pointed_point(frame, pointer)
        self.region, self._front = self._detect(frame)
        mask = self._full(frame, self._in_region(frame, self.region, self._front)) & self._seed
        self._good, self._reference_area, self.redetections = mask, int(np.count_nonzero(mask)), 0
        log.info("rgbd: object on frame %d: %.2f x %.2f x %.2f m box at %s m (base frame), %d pixels%s", frame.index,
                 *self.region.extent, np.round(self.region.center, 3).tolist(), self._reference_area,
                 f" within --box {self.config.box}" if self.config.box is not None else "")
        return mask

    def track(self, frame: Frame) -> np.ndarray:
        if self._good is None:
            raise PerceptionError("rgbd: track() called before start(); call start on the first frame")
        mask = self._follow(frame, self._good)
        if track_lost(mask, self._good, self._reference_area, self.config.min_area_ratio, 0.0) is not None:
            mask = self._recover(frame, mask)
        self._good = mask
        return mask

    # --- detection ----------------------------------------------------------------------------------------

    @staticmethod
    def _require_pose(frame: Frame) -> None:
        if frame.T_base_camera is None:
            raise PerceptionError(f"frame {frame.index} has no camera pose: the rgbd segmenter works in the arm's "
                                  "base frame; calibrate (`deploy calibrate hand-eye`) or give --calibration")

    def _detect(self, frame: Frame) -> tuple[Box, np.ndarray]:
        """The detected object's box and front direction (base frame); its pixels are left in `_seed`."""
        self._require_pose(frame)
        points, pixels = pixel_points(frame, DETECT_STEP, self._box_pixels(frame))
        reach = np.hypot(points[:, 0], points[:, 1])
        near = (reach >= self.config.detect_min_range_m) & (reach <= self.config.detect_max_range_m)
        points, pixels = points[near], pixels[near]
        keep = remove_floor(points)
        points, pixels = points[keep], pixels[keep]
        chosen = largest_object(points) if self._pointed is None else pointed_object(points, self._pointed)
        if len(chosen) == 0 and self._pointed is not None:
            raise PerceptionError(f"no object found on frame {frame.index} at the pointed point "
                                  f"{np.round(self._pointed, 2).tolist()} m (base frame): it is not within "
                                  f"{self.config.detect_max_range_m:.1f} m of the arm, or is the floor; point at the "
                                  "part to open")
        if len(chosen) == 0:
            raise PerceptionError(f"no object found on frame {frame.index}: nothing of a furniture's size stands "
                                  f"within {self.config.detect_max_range_m:.1f} m of the arm; point the camera at it, "
                                  "give --box X0 Y0 X1 Y1, or use the gdino-sam2 segmenter")
        viewpoint = np.asarray(frame.T_base_camera)[:3, 3]
        region = front_box(points[chosen], viewpoint)
        seed = np.zeros(frame.depth_m[::DETECT_STEP, ::DETECT_STEP].shape, np.uint8)
        seed[pixels[chosen, 0], pixels[chosen, 1]] = 1
        seed = cv2.dilate(seed, np.ones((3, 3), np.uint8))
        h, w = frame.depth_m.shape
        self._seed = cv2.resize(seed, (w, h), interpolation=cv2.INTER_NEAREST).astype(bool)
        return region, front_direction(region, viewpoint)

    def _box_pixels(self, frame: Frame) -> np.ndarray | None:
        if self.config.box is None:
            return None
        h, w = frame.depth_m.shape
        x0, y0, x1, y1 = (int(round(v)) for v in self.config.box)
        inside = np.zeros((h, w), bool)
        inside[max(y0, 0):max(min(y1, h), 0), max(x0, 0):max(min(x1, w), 0)] = True
        if not inside.any():
            raise PerceptionError(f"box {self.config.box} is empty or outside the {w}x{h} image: give a box "
                                  "X0 Y0 X1 Y1 around the object, in pixels")
        return inside

    # --- tracking -----------------------------------------------------------------------------------------

    def _in_region(self, frame: Frame, box: Box, front: np.ndarray) -> np.ndarray:
        """Every TRACK_STEP-th pixel whose point lies in the tracking region of `box` (a reduced image)."""
        half = box.extent / 2 + self.config.track_margin_m
        lo, hi = -half.copy(), half.copy()
        axis = int(np.argmax(np.abs(box.rotation.T @ front)))
        side = np.sign(box.rotation[:, axis] @ front)
        reach = max(self.config.opening_reach_m, float(np.max(np.delete(box.extent[:2], axis % 2))))
        (hi if side > 0 else lo)[axis] += side * reach
        points, pixels = pixel_points(frame, TRACK_STEP, None, *self._image_window(frame, box, lo, hi))
        local = (points - box.center) @ box.rotation
        inside = np.all((local >= lo) & (local <= hi), axis=1)
        inside &= points[:, 2] >= box.center[2] - box.extent[2] / 2 + FLOOR_CLEARANCE_M - self.config.track_margin_m
        small = np.zeros(frame.depth_m[::TRACK_STEP, ::TRACK_STEP].shape, bool)
        small[pixels[inside, 0], pixels[inside, 1]] = True
        return small

    @staticmethod
    def _image_window(frame: Frame, box: Box, lo: np.ndarray, hi: np.ndarray) -> tuple[slice, slice]:
        """Rows and columns of the reduced image the region (box-local corners `lo`, `hi`) projects into."""
        corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
        T = np.linalg.inv(frame.T_base_camera)
        cam = (corners @ box.rotation.T + box.center) @ T[:3, :3].T + T[:3, 3]
        h, w = frame.depth_m[::TRACK_STEP, ::TRACK_STEP].shape
        if cam[:, 2].min() <= 0.05:  # the region reaches behind the camera: search the whole image
            return slice(0, h), slice(0, w)
        uv = project(cam, frame.intrinsics.K, frame.intrinsics.dist_coeffs)
        (c0, r0), (c1, r1) = np.floor(uv.min(axis=0) / TRACK_STEP), np.ceil(uv.max(axis=0) / TRACK_STEP) + 1
        rows = slice(int(np.clip(r0, 0, h)), int(np.clip(r1, 0, h)))
        return rows, slice(int(np.clip(c0, 0, w)), int(np.clip(c1, 0, w)))

    def _full(self, frame: Frame, small: np.ndarray) -> np.ndarray:
        """A reduced mask at the frame's resolution, on the pixels with depth."""
        h, w = frame.depth_m.shape
        full = cv2.resize(small.astype(np.uint8), (small.shape[1] * TRACK_STEP, small.shape[0] * TRACK_STEP),
                          interpolation=cv2.INTER_NEAREST)[:h, :w].astype(bool)
        return full & (frame.depth_m > 0)

    def _follow(self, frame: Frame, previous: np.ndarray) -> np.ndarray:
        """What lies in the region and touches the previous mask in the image."""
        region = self._in_region(frame, self.region, self._front)
        near = cv2.dilate(previous[::TRACK_STEP, ::TRACK_STEP].astype(np.uint8), np.ones((5, 5), np.uint8))
        return self._full(frame, keep_touching(region, near.astype(bool)))

    def _recover(self, frame: Frame, followed: np.ndarray) -> np.ndarray:
        """The track shrank: detect the object again (the view may have changed, a door swung out of the region).
        When that finds nothing as large, what is left in the region is kept (the object is where it was, partly
        hidden); with nothing left after `max_redetections` attempts the object is lost."""
        for _ in range(self.config.max_redetections):
            self.redetections += 1
            try:
                region, front = self._detect(frame)
            except PerceptionError:
                break
            mask = self._full(frame, self._in_region(frame, region, front)) & self._seed
            if np.count_nonzero(mask) >= self.config.min_area_ratio * self._reference_area:
                self.region, self._front = region, front
                return mask
        if followed.any():
            return followed
        raise PerceptionError(
            f"rgbd segmenter lost the object at frame {frame.index}: nothing is left where it was and "
            f"{self.config.max_redetections} re-detection(s) found no object; keep it in view, or use the gdino-sam2 "
            "segmenter")


def open_rgbd(_argument: str, config: PerceptionConfig) -> RGBDSegmenter:
    return RGBDSegmenter(config)
