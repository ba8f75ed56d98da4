"""The moving part and the object mask on scripted kitchen openings, scored against the truth, and the axis the
screw estimators make of them: the static-scene moving part beside the paper's box cut.

The controller's side of each frame is what an episode has: the D415's depth, a camera pose calibrated with
CALIBRATION_ERROR, the arm's pixels removed by the self-filter from its joints. The first frame's target front and
furniture (what the user's pointer gives) come from the truth here, standing in for the pointer's perception.

Methods:
- "static": the static-scene moving part in the opening region of the target's front; masks from the
  StaticSceneTracker on the first frame's furniture;
- "static-body": the same without a front: the region of the first frame's furniture (the pipeline's default);
- "box-oracle": the paper's box cut on the truth's furniture mask (minus the arm), as `deploy axis estimate` gets on
  a recording;
- "box-rgbd": the box cut on today's `rgbd` segmenter's masks (its own detection).

Per frame the moving part's pixels are classed by the truth: the target part, the rest of its furniture, the arm,
the scene (neighbours, counter, wall, floor, objects). A scene pixel within EDGE_MIXING_PX of the target part's pixels
is counted apart: the stereo matching gives the part's depth to pixels beside its edge (edge widening, flying
pixels), so such a pixel holds the part's surface, whatever the ray caster's label says.
"""

from __future__ import annotations

import time
import zlib

import cv2
import numpy as np

from deploy.axis_pipeline import AxisPipeline
from deploy.bench.motion_record import MotionEpisode
from deploy.config import CALIBRATION_ERROR, Config
from deploy.geometry.cloud import points_to_pixels
from deploy.geometry.estimators.base import AxisEstimator
from deploy.geometry.metrics import axis_angle_error_deg, axis_position_error_m
from deploy.geometry.static_scene import EDGE_REACH_PX
from deploy.geometry.types import Axis, NoAxis
from drivers.camera.base import Frame, Intrinsics

METHODS = ("static", "static-body", "box-oracle", "box-rgbd")
ESTIMATORS = ("screw", "screw-grip")
EDGE_MIXING_PX = EDGE_REACH_PX  # a D415 pixel may hold the depth of a surface this far away (static_scene.py)
MOVED = {"prismatic": 0.02, "revolute": np.radians(5.0)}  # frames scored for recall: the part opened this much
OTHERS_MOVED = 0.01  # m or rad: another part moved (bumped, or swinging by itself): whatever it shows does move


class _MovingOnly(AxisEstimator):
    """No estimate: the pipeline runs for its moving part only."""

    name = "none"

    def estimate(self, window, joint=None):
        return NoAxis("moving part only")


def sensed_frames(episode: MotionEpisode, seed: int) -> list[tuple[Frame, np.ndarray, float]]:
    """Each frame as the controller gets it (calibrated pose, the arm's depth removed) with the arm's mask and the
    self-filter's CPU ms."""
    from deploy.perception.bench import _self_filter
    from deploy.rig import simulated_calibration

    info = episode.info
    T = simulated_calibration(np.asarray(info["T_true"]), *CALIBRATION_ERROR, np.random.default_rng(seed))
    K = np.asarray(info["K"])
    h, w = episode.depth_mm.shape[1:]
    intrinsics = Intrinsics(w, h, K[0, 0], K[1, 1], K[0, 2], K[1, 2])
    self_filter, _ = _self_filter()
    color = np.zeros((h, w, 3), np.uint8)
    out = []
    for i in range(len(episode.depth_mm)):
        frame = Frame(i, i / 5.0, color, episode.depth_mm[i].astype(np.float32) / 1000.0, intrinsics, T)
        clock = time.thread_time()
        seen, robot = self_filter.apply(frame, episode.q[i], float(episode.width_m[i]))
        out.append((seen, robot, (time.thread_time() - clock) * 1e3))
    return out


def truth_classes(episode: MotionEpisode, i: int) -> dict[str, np.ndarray]:
    """(H, W) masks of frame i from the truth: part, furniture (the rest of its body), robot, scene, edge (within
    EDGE_MIXING_PX of the part)."""
    info = episode.info
    body, link = episode.links[i, ..., 0], episode.links[i, ..., 1]
    own = body == info["body"]
    part = own & np.isin(link, info["part_links"])
    robot = body == info["robot"]
    distance = cv2.distanceTransform((~part).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return {"part": part, "furniture": own & ~part, "robot": robot, "scene": (body >= 0) & ~own & ~robot,
            "edge": distance <= EDGE_MIXING_PX}


def first_masks(episode: MotionEpisode, robot: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The first frame's target front (the part's own link, not its handle) and furniture, as the pointer would give
    them (truth standing in for it), without the arm's pixels."""
    info = episode.info
    body, link = episode.links[0, ..., 0], episode.links[0, ..., 1]
    own = (body == info["body"]) & ~robot
    return own & (link == info["part_links"][0]), own


def classify(points: np.ndarray, frame: Frame, classes: dict[str, np.ndarray]) -> dict[str, int]:
    """How many moving points fall on each truth class (points projected back to their pixels)."""
    K = frame.intrinsics
    uv = np.round(points_to_pixels(points, K.K, frame.T_base_camera)).astype(int)
    u, v = np.clip(uv[:, 0], 0, K.width - 1), np.clip(uv[:, 1], 0, K.height - 1)
    scene, furniture, beyond = classes["scene"][v, u], classes["furniture"][v, u], ~classes["edge"][v, u]
    return {"points": len(points), "part": int(classes["part"][v, u].sum()), "furniture": int(furniture.sum()),
            "furniture_beyond_edge": int((furniture & beyond).sum()), "robot": int(classes["robot"][v, u].sum()),
            "scene": int(scene.sum()), "scene_beyond_edge": int((scene & beyond).sum())}


def _config(method: str, estimator: str, joint: str) -> Config:
    box = method.startswith("box")
    return Config().for_camera("sim").replace(
        geometry={"moving_part": "box" if box else "static-scene"},
        estimator={"name": estimator, "joint": joint})


def _masks(method: str, sensed: list[tuple[Frame, np.ndarray]], episode: MotionEpisode, region) -> list:
    """Each frame's object mask (minus the arm) for `method`, and the CPU ms each took."""
    from deploy.perception.registry import make_segmenter
    from deploy.perception.static_tracker import StaticSceneTracker, front_region

    frame0, robot0, _ = sensed[0]
    front, furniture = first_masks(episode, robot0)
    out = []
    if method == "box-oracle":
        for i, (_, robot, _) in enumerate(sensed):
            body = episode.links[i, ..., 0] == episode.info["body"]
            out.append((body & ~robot, 0.0))
        return out
    if method == "box-rgbd":
        segmenter = make_segmenter("rgbd")
        track = segmenter.track
        first = segmenter.start(frame0)
    else:
        region = region if method == "static" else front_region(frame0, furniture, 0.6)
        track = StaticSceneTracker(frame0, furniture, region).track
        first = furniture
    out.append((first & ~robot0, 0.0))
    for frame, robot, _ in sensed[1:]:
        clock = time.thread_time()
        mask = track(frame) & ~robot
        out.append((mask, (time.thread_time() - clock) * 1e3))
    return out


def _final_axis_errors(result, episode: MotionEpisode, at: np.ndarray) -> dict:
    """The final estimate's angle error (deg) and, for a hinge, its distance from the true axis at `at` (m)."""
    info = episode.info
    if not isinstance(result, Axis):
        return {"angle_deg": None, "position_m": None, "reason": getattr(result, "reason", "no frames")}
    angle = axis_angle_error_deg(np.asarray(info["direction"]), result.direction)
    position = None
    if info["joint_type"] == "revolute":
        position = axis_position_error_m(np.asarray(info["origin"]), np.asarray(info["direction"]), result.origin,
                                         result.direction, at=at)
    return {"angle_deg": angle, "position_m": position}


def _axis_run(method: str, estimator: str, sensed: list, masks: list, episode: MotionEpisode, region) -> dict:
    """The axis pipeline over the first frame and the frames where the gripper held the handle (as `deploy axis
    estimate`), its final estimate's errors and per held frame the CPU ms of self-filter, mask and pipeline."""
    pipe = AxisPipeline(_config(method, estimator, episode.info["joint_type"]),
                        region=region if method == "static" else None)
    final, ms = NoAxis("no frame held the handle"), []
    for i, ((frame, _, filter_ms), (mask, mask_ms)) in enumerate(zip(sensed, masks, strict=True)):
        if i > 0 and not episode.grasped[i]:
            continue
        clock = time.thread_time()
        step = pipe.update_frame(frame, mask, episode.ee_pose[i] if episode.grasped[i] else None)
        if i > 0:
            ms.append(filter_ms + mask_ms + (time.thread_time() - clock) * 1e3)
        final = step.result if isinstance(step.result, Axis) or not isinstance(final, Axis) else final
    held = np.flatnonzero(episode.grasped)
    at = episode.ee_pose[held[0], :3, 3] if len(held) else np.asarray(episode.info["origin"])
    return {**_final_axis_errors(final, episode, at), "frame_ms": ms}


def score_episode(episode: MotionEpisode, methods: tuple[str, ...] = METHODS) -> dict:
    """Per method: per-frame moving-part classes (frames 1..n), the object mask's IoU with the furniture (minus the
    arm) and its share on the scene, and per estimator the final axis errors and per-frame CPU ms. The calibration's
    error is drawn from the episode's source and seed."""
    from deploy.perception.static_tracker import front_region

    sensed = sensed_frames(episode, zlib.crc32(f"{episode.info['source']} {episode.info['seed']}".encode()))
    front, _ = first_masks(episode, sensed[0][1])
    region = front_region(sensed[0][0], front, 0.6)
    classes = [truth_classes(episode, i) for i in range(len(sensed))]
    out = {"info": episode.info, "moved": _moved(episode).tolist(),
           "others_moved": (episode.others_moved > OTHERS_MOVED).tolist(), "methods": {}}
    for method in methods:
        try:
            masks = _masks(method, sensed, episode, region)
        except Exception as exc:  # a segmenter that finds nothing: the method fails on this episode
            out["methods"][method] = {"failed": f"{type(exc).__name__}: {exc}"}
            continue
        pipe = AxisPipeline(_config(method, "screw", episode.info["joint_type"]), estimator=_MovingOnly(),
                            region=region if method == "static" else None)
        frames = []
        for i, ((frame, robot, _), (mask, _)) in enumerate(zip(sensed, masks, strict=True)):
            step = pipe.update_frame(frame, mask)
            if i == 0:
                continue
            furniture = (episode.links[i, ..., 0] == episode.info["body"]) & ~robot
            counts = classify(step.moving, frame, classes[i])
            counts["visible_part"] = int((classes[i]["part"] & (frame.depth_m > 0))[::2, ::2].sum())
            counts["mask_iou"] = _iou(mask, furniture)
            counts["mask_on_scene"] = float((mask & classes[i]["scene"]).sum() / max(1, mask.sum()))
            frames.append(counts)
        out["methods"][method] = {"frames": frames, "axes": {
            name: _axis_run(method, name, sensed, masks, episode, region) for name in ESTIMATORS}}
    return out


def _moved(episode: MotionEpisode) -> np.ndarray:
    """Per frame, whether the part has opened enough to score recall (MOVED)."""
    opened = np.abs(episode.joint_value - episode.joint_value[0])
    return opened >= MOVED[episode.info["joint_type"]]


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return 1.0 if union == 0 else np.count_nonzero(a & b) / union


def summarise(results: list[dict]) -> dict:
    """Per task and method: the moving part's precision and recall per frame (median, p10), the share of frames
    where the scene (beyond the part's edge and at all), the part's own furniture or the arm counts as moving, the
    object mask's IoU and its largest share on the scene; per estimator the axis errors (median, p90, max; a
    missing estimate counts as 90 deg) and per-frame CPU ms (median, p90)."""
    out: dict = {}
    for task in ("drawer", "door"):
        episodes = [r for r in results if r["info"]["task"] == task]
        if not episodes:
            continue
        out[task] = {"episodes": len(episodes)}
        out[task]["episodes_with_other_parts_moving"] = sum(any(r["others_moved"]) for r in episodes)
        for method in METHODS:
            runs = [(r, r["methods"].get(method, {})) for r in episodes]
            failed = [run for _, run in runs if "failed" in run]
            scored = [(r, run) for r, run in runs if "frames" in run]
            out[task][method] = {"failed": len(failed), **_frame_figures(scored), **_axis_figures(scored)}
    return out


def _frame_figures(scored: list[tuple[dict, dict]]) -> dict:
    """Frames where another part moved (OTHERS_MOVED) do not count toward the scene's shares: it did move."""
    frames = [f for _, run in scored for f in run["frames"]]
    still = [f for r, run in scored for f, other in zip(run["frames"], r["others_moved"][1:], strict=True)
             if not other]
    opened = [f for r, run in scored for f, m in zip(run["frames"], r["moved"][1:], strict=True) if m]
    precision = [f["part"] / f["points"] for f in opened if f["points"]]
    recall = [f["part"] / f["visible_part"] for f in opened if f["visible_part"]]
    n, m = max(1, len(frames)), max(1, len(still))
    return {
        "frames": len(frames), "opened_frames": len(opened), "frames_others_still": len(still),
        "precision_median": _q(precision, 50), "precision_p10": _q(precision, 10),
        "recall_median": _q(recall, 50), "recall_p10": _q(recall, 10),
        "frames_scene_moving_beyond_edge": sum(f["scene_beyond_edge"] > 0 for f in still) / m,
        "frames_scene_moving": sum(f["scene"] > 0 for f in still) / m,
        "frames_own_furniture_moving_beyond_edge": sum(f["furniture_beyond_edge"] > 0 for f in still) / m,
        "frames_own_furniture_moving": sum(f["furniture"] > 0 for f in still) / m,
        "frames_arm_moving": sum(f["robot"] > 0 for f in frames) / n,
        "mask_iou_median": _q([f["mask_iou"] for f in frames], 50),
        "mask_on_scene_max": max((f["mask_on_scene"] for f in still), default=None),
    }


def _axis_figures(scored: list[tuple[dict, dict]]) -> dict:
    figures = {}
    for name in ESTIMATORS:
        axes = [run["axes"][name] for _, run in scored]
        angles = [90.0 if a["angle_deg"] is None else a["angle_deg"] for a in axes]
        positions = [a["position_m"] for a in axes if a["position_m"] is not None]
        ms = [m for a in axes for m in a["frame_ms"]]
        figures[name] = {"angle_deg_median": _q(angles, 50), "angle_deg_p90": _q(angles, 90),
                         "angle_deg_max": _q(angles, 100), "no_estimate": sum(a["angle_deg"] is None for a in axes),
                         "hinge_m_median": _q(positions, 50), "hinge_m_p90": _q(positions, 90),
                         "frame_ms_median": _q(ms, 50), "frame_ms_p90": _q(ms, 90)}
    return figures


def _q(values: list[float], q: float) -> float | None:
    return None if not values else round(float(np.percentile(values, q)), 4)
