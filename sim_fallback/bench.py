"""Simulation speed (`bench sim`): physics steps per second, what a camera frame costs and the real-time factor
of an opening, on the drawer scenarios of a world (`kitchen`: the seeded kitchens of docs/kitchens.md; `box`: one
cabinet in empty space). The simulated D415's depth on walls (`bench depth`): fill rate and error of both depth
models.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pybullet as pb

from drivers.arm.robot_config import panda_sim_config
from drivers.arm.trajectory import MotionLimits
from drivers.camera.depth_noise import DepthNoise
from sim_fallback.arm import SimArm
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.camera_scenes import look_along_x, wall
from sim_fallback.errors import SceneError
from sim_fallback.furniture import Finish
from sim_fallback.render.renderer import RayRenderer
from sim_fallback.render.stereo import ActiveStereo
from sim_fallback.scenario import make_scenario
from sim_fallback.scripted import grasp_handle, open_along_truth
from sim_fallback.world import SimWorld
from sim_fallback.worlds import WORLDS

OPENING_S = 10.0  # simulated duration of the timed opening
OPENING_M = 0.2  # drawer travel during it (a slow, steady pull)
PHYSICS_TICKS = 2400
HD_RENDERS = 3
DEPTH_MODELS = {"model": DepthNoise.d415, "stereo": ActiveStereo, "exact": DepthNoise.none}


def bench_sim(episodes: int = 1, world: str = "kitchen", progress: Callable[[str], None] | None = None) -> dict:
    """Speed of the simulation on this machine (medians over `episodes` drawer scenarios); progress(what) names
    each phase as it starts.

    physics_steps_per_s: arm ticks (holding still, one 240 Hz physics step each) per wall second;
    frame_ms / frame_ms_stereo: a 640x480 frame's cost by step (medians over the frames of the opening, the
    D415 artefact model / active stereo as the depth model); first_frame_ms: the first frame (the static scene's
    hits, looks and light, computed once per camera pose); render_ms_1280x720: a whole 1280x720 frame;
    real_time_factor: simulated / wall time of a 10 s scripted opening (IK and safety checks every tick) with a
    640x480 frame every 0.1 s and the default depth model (the artefact model); _stereo: active stereo; _exact:
    exact depth; _cpu: simulated / the process's CPU time (what a core of its own would give on a busy machine).
    """
    if world not in WORLDS:
        raise SceneError(f"--world {world!r} is not a world: use one of {', '.join(WORLDS)}")
    steps, hd, first = [], [], []
    rtf, rtf_cpu = {name: [] for name in DEPTH_MODELS}, {name: [] for name in DEPTH_MODELS}
    frames: dict[str, list[dict]] = {"model": [], "stereo": []}
    show = progress or (lambda _what: None)
    for seed in range(episodes):
        where = f"episode {seed + 1}/{episodes}: " if episodes > 1 else ""
        show(f"{where}{PHYSICS_TICKS} physics steps")
        with _world(seed, world) as w:
            arm = SimArm(w)
            t0 = time.perf_counter()
            for _ in range(PHYSICS_TICKS):
                arm.sync()
            steps.append(PHYSICS_TICKS / (time.perf_counter() - t0))
            show(f"{where}{HD_RENDERS} frames at 1280x720")
            camera = SimCamera(w, intrinsics=d415_intrinsics(1280, 720))
            t0 = time.perf_counter()
            camera.read()
            first.append(1e3 * (time.perf_counter() - t0))
            hd.append(_median_ms(camera.read, HD_RENDERS))
        for name, model in DEPTH_MODELS.items():
            show(f"{where}a {OPENING_S:g} s scripted opening, depth: {name}")
            with _world(seed, world) as w:
                factor, factor_cpu, timings = _opening(w, SimArm(w), model())
            rtf[name].append(factor)
            rtf_cpu[name].append(factor_cpu)
            frames.get(name, []).extend(timings)
    return {
        "world": world,
        "episodes": episodes,
        "physics_steps_per_s": float(np.median(steps)),
        "frame_ms": _median_steps(frames["model"]),
        "frame_ms_stereo": _median_steps(frames["stereo"]),
        "first_frame_ms_1280x720": float(np.median(first)),
        "render_ms_1280x720": float(np.median(hd)),
        "real_time_factor": float(np.median(rtf["model"])),
        "real_time_factor_stereo": float(np.median(rtf["stereo"])),
        "real_time_factor_exact": float(np.median(rtf["exact"])),
        "real_time_factor_cpu": float(np.median(rtf_cpu["model"])),
        "real_time_factor_stereo_cpu": float(np.median(rtf_cpu["stereo"])),
    }


def _world(seed: int, world: str) -> SimWorld:
    return SimWorld(make_scenario(world, "drawer", seed))


def _median_ms(fn, n: int) -> float:
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def _median_steps(timings: list[dict]) -> dict[str, float]:
    """Per step, the median over frames (the first frame, which builds the static layer, left out), and the
    median total, in wall time and in CPU time."""
    later = timings[1:] or timings
    steps = sorted({k for t in later for k in t if k not in ("static layer", "cpu")})
    out = {k: round(float(np.median([t.get(k, 0.0) for t in later])), 2) for k in steps}
    out["total"] = round(float(np.median([sum(t.get(k, 0.0) for k in steps) for t in later])), 2)
    out["total_cpu"] = round(float(np.median([t["cpu"] for t in later])), 2)
    return out


def _opening(world: SimWorld, arm: SimArm, noise: DepthNoise | ActiveStereo) -> tuple[float, float, list[dict]]:
    """Grasp (untimed), then time a ground-truth opening lasting OPENING_S with frames at 10 Hz: the real-time
    factor over wall time and over the process's CPU time, and each frame's timings (ms by step, wall; `cpu`: the
    frame's CPU time)."""
    grasp_handle(world, arm, panda_sim_config().motion_limits(arm.kin, 0.3), OPENING_M)
    camera = SimCamera(world, noise=noise, fps=10.0)
    v = OPENING_M / (OPENING_S - 1.0)  # cruise speed; about 1 s goes to speeding up and braking
    limits = MotionLimits(v, 2 * v, 20 * v)
    next_t = world.time
    timings = []

    def grab(state, _t: float) -> None:
        nonlocal next_t
        if state.t >= next_t - 1e-9:
            cpu = time.process_time()
            next_t = (camera.read().index + 1) / camera.fps
            timings.append({**camera.timings_ms, "cpu": 1e3 * (time.process_time() - cpu)})

    sim0, wall0, cpu0 = world.time, time.perf_counter(), time.process_time()
    open_along_truth(world, arm, OPENING_M, limits, grab)
    simulated = world.time - sim0
    return simulated / (time.perf_counter() - wall0), simulated / (time.process_time() - cpu0), timings


WALL_DISTANCES_M = (0.5, 1.0, 2.0)
WALL_SURFACES = {"plain": None, "wood": Finish("wood", (0.45, 0.3, 0.18), 0.15, 7),
                 "dark": Finish("painted", (0.03, 0.03, 0.03), 0.3, 0)}
WALL_FRAMES = 3
D415_RMS_PCT_AT_2M = 2.0  # datasheet: RMS error under 2 % of the distance at 2 m, central 80 % of the image


def bench_depth(progress: Callable[[str], None] | None = None) -> dict:
    """Fill rate and error of both depth models on a wall facing the camera, 640x480: per (model, surface,
    distance) the fill rate over the image and over its central 80 %, the RMS depth error there (% of the
    distance; valid pixels), the left band's width (the first column where most rows have depth) and f B / Z."""
    show = progress or (lambda _what: None)
    intrinsics = d415_intrinsics()
    T = look_along_x()
    rows = []
    for model_name in ("model", "stereo"):
        for surface, finish in WALL_SURFACES.items():
            for z in WALL_DISTANCES_M:
                show(f"{model_name}, {surface} wall at {z:g} m")
                depth, truth = _wall_frames(DEPTH_MODELS[model_name](), finish, z, T, intrinsics)
                rows.append({"model": model_name, "surface": surface, "distance_m": z, **_depth_figures(
                    depth, truth, intrinsics.fx * 0.055 / z)})
    return {"resolution": [intrinsics.width, intrinsics.height], "frames": WALL_FRAMES,
            "d415_rms_pct_at_2m": D415_RMS_PCT_AT_2M, "rows": rows}


def _wall_frames(noise, finish: Finish | None, z: float, T: np.ndarray, intrinsics) -> tuple[np.ndarray, ...]:
    """WALL_FRAMES depth images of a wall `z` away (stacked) and the exact depth."""
    client = pb.connect(pb.DIRECT)
    try:
        body = wall(client, z)
        renderer = RayRenderer(client, intrinsics, {} if finish is None else {(body, -1): finish})
        rng = np.random.default_rng(0)
        frames = []
        for _ in range(WALL_FRAMES):
            if isinstance(noise, ActiveStereo):
                projector = noise.projector(T)
                view = renderer.render(T, rng, (projector,))
                right = renderer.see("right", noise.right(T), (projector,))
                frames.append(noise.measure(view.seen, right, T, intrinsics, rng))
            else:
                view = renderer.render(T, rng)
                frames.append(noise.apply(view.depth_m, intrinsics.fx, rng, reflectance=view.reflectance))
        return np.stack(frames), view.depth_m
    finally:
        pb.disconnect(client)


def _depth_figures(depth: np.ndarray, truth: np.ndarray, band_px: float) -> dict:
    n, h, w = depth.shape
    central = np.zeros((h, w), bool)
    central[round(0.1 * h):round(0.9 * h), round(0.1 * w):round(0.9 * w)] = True
    valid = depth > 0
    inside = valid & central
    error = ((depth - truth) / np.where(truth > 0, truth, np.inf))[inside]
    filled_columns = valid.mean(axis=(0, 1)) > 0.5
    return {"fill": round(float(valid.mean()), 4), "fill_central": round(float(inside.sum() / (n * central.sum())), 4),
            "rms_error_pct": round(100 * float(np.sqrt(np.mean(error ** 2))), 3) if error.size else None,
            "left_band_px": int(np.argmax(filled_columns)) if filled_columns.any() else w,
            "expected_band_px": round(band_px, 1)}
