"""The pointer's benchmark: from the simulated user's pixel to the front, its furniture and its handle, scored
against the world's truth, in kitchens and on PartNet-Mobility objects placed in them.

Per scene: the first frame as the controller gets it (colour, D415 depth, a calibrated pose off by CALIBRATION_ERROR,
the arm's pixels from the self-filter at the arm's start), the user's pixel (sim_fallback.user), `point_at`. Scored:
front mask IoU (the target part's link, its handle links left out), furniture mask IoU (the target body's pixels),
the grip centre's error against `world.target_handle()`, the style against the truth's, and the time. Bad input:
pixels off the image, on the floor, a wall and the counter must each be refused with a PointerError.

    python -m deploy.bench.pointer --split test --seeds 50 [--assets ../shared/partnet-mobility-dev] [--json]
"""

from __future__ import annotations

import argparse
import json
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from deploy.config import CALIBRATION_ERROR
from deploy.errors import PointerError
from deploy.perception.base import Pointer
from deploy.perception.pointing import point_at

STYLE_CLASSES = {"bar": "bar", "long-bar": "bar", "knob": "knob", "edge-pull": "pull", "recessed": "pull",
                 "cup": "pull", "none": "none"}
BAD_INPUTS = ("floor", "wall", "countertop")  # static shapes the user may point at by mistake


def bench_scene(task: str, seed: int, split: str, target=None, part: str | None = None) -> dict:
    """One scene's scores (see the module docstring)."""
    from deploy.rig import simulated_calibration
    from sim_fallback.camera import SimCamera
    from sim_fallback.errors import SceneError
    from sim_fallback.scenario import make_scenario
    from sim_fallback.user import user_pixel
    from sim_fallback.world import SimWorld

    row = {"task": task, "seed": seed, "split": split, "part": part or "", "source": getattr(target, "source",
                                                                                           "procedural")}
    try:
        scenario = make_scenario("kitchen", task, seed, split, part=part, target=target)  # type: ignore[arg-type]
    except SceneError as e:  # a part out of the robot's reach, say
        return {**row, "error": f"no scene: {e}", "scene_error": True}
    names = [shape.name for shape in scenario.build_layout().statics]
    with SimWorld(scenario) as world:
        camera = SimCamera(world, seed=seed)
        frame, links, truth = camera.read(), camera.link_image(), world.truth()
        pose = simulated_calibration(camera.T_base_camera, *CALIBRATION_ERROR, np.random.default_rng([seed, 7]))
        frame = replace(frame, T_base_camera=pose)
        robot = _robot_pixels(frame, np.asarray(scenario.q_start))
        pixel = user_pixel(links, truth.body_id, truth.links[0], truth.links, np.random.default_rng([seed, 3]))
        grip = world.target_handle()[0]
        style = world.target.part.handle.style if world.target.part.handle else "none"
        statics = _static_pixels(links, world.statics_id, names)
    body, link = links[..., 0], links[..., 1]
    front_truth = (body == truth.body_id) & (link == truth.links[0]) & ~robot
    furniture_truth = (body == truth.body_id) & ~robot
    row = {**row, "part": truth.part, "style": style}
    if pixel is None:
        return {**row, "error": "the target part is not seen"}
    start = time.perf_counter()
    try:
        found = point_at(frame, robot, Pointer(*pixel))
    except PointerError as e:
        return {**row, "error": str(e), "ms": (time.perf_counter() - start) * 1e3,
                "bad_inputs": _bad_inputs(frame, robot, statics)}
    ms = (time.perf_counter() - start) * 1e3
    return {**row, "ms": ms, "front_iou": _iou(found.front.mask, front_truth),
            "furniture_iou": _iou(found.furniture.mask, furniture_truth),
            "handle_error_m": float(np.linalg.norm(found.handle.centre - grip)),
            "style_found": found.handle.style, "kind_found": found.handle.kind,
            "style_correct": found.handle.style == STYLE_CLASSES.get(style, style),
            "front_ended": found.front.ended, "bad_inputs": _bad_inputs(frame, robot, statics)}


def _robot_pixels(frame, q: np.ndarray) -> np.ndarray:
    """The self-filter's mask of the simulated Panda at joints `q`, its gripper open (as the world builds it)."""
    from deploy.perception.self_filter import SelfFilter
    from drivers.arm.body import RobotBody
    from drivers.arm.robot_config import PANDA_SIM_CONFIG, load_robot_config

    robot = load_robot_config(PANDA_SIM_CONFIG)
    width = robot.gripper.max_width_m if robot.gripper else 0.0
    return SelfFilter(RobotBody.from_robot(robot)).mask(frame, q, width)


def _static_pixels(links: np.ndarray, statics_id: int, names: list[str]) -> dict[str, np.ndarray]:
    """Per bad-input surface (floor, wall, countertop): its pixels (the static shapes' links are in layout order,
    the first one the body's base)."""
    out = {}
    for name in BAD_INPUTS:
        ks = [k - 1 for k, n in enumerate(names) if n == name]
        out[name] = (links[..., 0] == statics_id) & np.isin(links[..., 1], ks)
    return out


def _bad_inputs(frame, robot: np.ndarray, statics: dict[str, np.ndarray]) -> dict[str, str]:
    """The line `point_at` gives for a pixel off the image and for a pixel well inside the floor, a wall and the
    counter ("accepted" when it found a front there, "not seen" when the surface is not in view)."""
    import cv2

    h, w = frame.depth_m.shape
    lines = {}
    tries = {"off the image": (w + 5, h // 2)}
    for name, pixels in statics.items():
        padded = np.pad((pixels & ~robot).astype(np.uint8), 1)  # the image's border counts as an edge
        inset = cv2.distanceTransform(padded, cv2.DIST_L2, 5)[1:-1, 1:-1]
        if inset.max() < 4:
            lines[name] = "not seen"
            continue
        v, u = np.unravel_index(int(np.argmax(inset)), inset.shape)
        tries[name] = (int(u), int(v))
    for name, pixel in tries.items():
        try:
            point_at(frame, robot, Pointer(*pixel))
            lines[name] = "accepted"
        except PointerError as e:
            lines[name] = str(e)
    return lines


def _iou(a: np.ndarray, b: np.ndarray) -> float:
    union = np.count_nonzero(a | b)
    return float(np.count_nonzero(a & b) / union) if union else 0.0


def summary(rows: list[dict]) -> dict:
    """Median, p90 (or p10 for IoUs), worst and failure causes over `rows`."""
    done = [r for r in rows if "front_iou" in r]
    scenes = [r for r in rows if not r.get("scene_error")]
    out: dict = {"scenes": len(scenes), "found": len(done),
                 "refused": {f"{r['source']} {r['part']} seed {r['seed']}": r["error"] for r in scenes if "error" in r},
                 "no_scene": {f"{r['source']} {r['part']}": r["error"] for r in rows if r.get("scene_error")}}
    for key, low_is_bad in (("front_iou", True), ("furniture_iou", True), ("handle_error_m", False), ("ms", False)):
        values = np.array([r[key] for r in done], float)
        if len(values):
            out[key] = {"median": round(float(np.median(values)), 4),
                        ("p10" if low_is_bad else "p90"): round(float(np.percentile(values, 10 if low_is_bad else 90)),
                                                                4),
                        "worst": round(float(values.min() if low_is_bad else values.max()), 4)}
    if done:
        errors = np.array([r["handle_error_m"] for r in done])
        out["handle_within_2cm"] = round(float(np.mean(errors <= 0.02)), 3)
        out["handle_within_5cm"] = round(float(np.mean(errors <= 0.05)), 3)
        out["style_correct"] = round(float(np.mean([r["style_correct"] for r in done])), 3)
    bad = [r["bad_inputs"] for r in rows if "bad_inputs" in r]
    out["bad_inputs_refused"] = {name: f"{sum(b.get(name, '') not in ('accepted', 'not seen', '') for b in bad)}/"
                                       f"{sum(b.get(name, 'not seen') != 'not seen' for b in bad)}"
                                 for name in ("off the image", *BAD_INPUTS)}
    return out


def partnet_targets(assets: Path) -> list[tuple]:
    """(furniture, part name, kind) for every drawer and door part of every object in `assets`."""
    from sim_fallback.partnet import load_partnet

    targets = []
    for folder in sorted(p for p in Path(assets).iterdir() if (p / "mobility.urdf").exists()):
        furniture = load_partnet(folder)
        targets += [(furniture, part.name, part.kind) for part in furniture.parts]
    return targets


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--split", default="test")
    parser.add_argument("--seeds", type=int, default=50)
    parser.add_argument("--first-seed", type=int, default=0)
    parser.add_argument("--tasks", default="drawer,door")
    parser.add_argument("--assets", type=Path, default=None)
    parser.add_argument("--json", type=Path, default=None, help="write every scene's row and the summaries here")
    args = parser.parse_args(argv)
    results: dict = {}
    if args.assets is None:
        for task in args.tasks.split(","):
            rows = [bench_scene(task, seed, args.split) for seed in range(args.first_seed,
                                                                          args.first_seed + args.seeds)]
            results[task] = {"summary": summary(rows), "rows": rows}
            print(task, json.dumps(results[task]["summary"], indent=1))
    else:
        rows = [bench_scene(kind, k, args.split, target=furniture, part=part)
                for k, (furniture, part, kind) in enumerate(partnet_targets(args.assets))]
        results["partnet"] = {"summary": summary(rows), "rows": rows}
        print("partnet", json.dumps(results["partnet"]["summary"], indent=1))
        for r in rows:
            print(r["source"], r["part"], {k: r.get(k) for k in ("front_iou", "furniture_iou", "handle_error_m",
                                                                  "style", "style_found", "error")})
    if args.json is not None:
        args.json.write_text(json.dumps(results, indent=1, default=str))


if __name__ == "__main__":
    main()
