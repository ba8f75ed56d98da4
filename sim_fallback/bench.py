"""Simulation speed: physics steps per second, render time per frame, real-time factor of an opening."""

from __future__ import annotations

import time
from collections.abc import Callable
from functools import partial

import numpy as np

from drivers.arm.robot_config import panda_sim_config
from drivers.arm.trajectory import MotionLimits
from drivers.camera.depth_noise import DepthNoise
from sim_fallback.arm import SimArm
from sim_fallback.camera import SimCamera, d415_intrinsics
from sim_fallback.scenario import Scenario
from sim_fallback.scripted import grasp_handle, open_along_truth
from sim_fallback.world import SimWorld

OPENING_S = 10.0  # simulated duration of the timed opening
OPENING_M = 0.2  # drawer travel during it (a slow, steady pull)
PHYSICS_TICKS = 2400
RENDERS = 5


def bench_sim(episodes: int = 1, progress: Callable[[str], None] | None = None) -> dict:
    """Speed of the simulation on this machine (medians over `episodes` drawer scenarios); progress(what) names
    each phase as it starts.

    physics_steps_per_s: arm ticks (holding still, one 240 Hz physics step each) per wall second;
    render_ms_*: one frame rendered and its segmentation decoded; depth_noise_ms_640x480: the D415
    noise model on it; real_time_factor: simulated / wall time of a 10 s scripted opening (IK and
    safety checks every tick) with a 640x480 frame every 0.1 s, D415 noise on (and off).
    """
    steps, render_vga, render_hd, noise_ms, rtf, rtf_clean = [], [], [], [], [], []
    show = progress or (lambda _what: None)
    for seed in range(episodes):
        where = f"episode {seed + 1}/{episodes}: " if episodes > 1 else ""
        show(f"{where}{PHYSICS_TICKS} physics steps")
        with SimWorld(Scenario.make("drawer", seed)) as world:
            arm = SimArm(world)
            t0 = time.perf_counter()
            for _ in range(PHYSICS_TICKS):
                arm.sync()
            steps.append(PHYSICS_TICKS / (time.perf_counter() - t0))
            show(f"{where}rendering ({RENDERS} frames at 640x480 and 1280x720) and depth noise")
            for size, out in (((640, 480), render_vga), ((1280, 720), render_hd)):
                out.append(_median_ms(SimCamera(world, intrinsics=d415_intrinsics(*size)).render, RENDERS))
            _, depth, _ = SimCamera(world).render()
            noisy = partial(DepthNoise.d415().apply, depth, d415_intrinsics().fx, np.random.default_rng(seed))
            noise_ms.append(_median_ms(noisy, RENDERS))
        for noise, out, label in ((DepthNoise.d415(), rtf, "on"), (DepthNoise.none(), rtf_clean, "off")):
            show(f"{where}a {OPENING_S:g} s scripted opening, depth noise {label}")
            with SimWorld(Scenario.make("drawer", seed)) as world:
                out.append(_opening_real_time_factor(world, SimArm(world), noise))
    return {
        "episodes": episodes,
        "physics_steps_per_s": float(np.median(steps)),
        "render_ms_640x480": float(np.median(render_vga)),
        "render_ms_1280x720": float(np.median(render_hd)),
        "depth_noise_ms_640x480": float(np.median(noise_ms)),
        "real_time_factor": float(np.median(rtf)),
        "real_time_factor_noise_off": float(np.median(rtf_clean)),
    }


def _median_ms(fn, n: int) -> float:
    times = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return 1e3 * float(np.median(times))


def _opening_real_time_factor(world: SimWorld, arm: SimArm, noise: DepthNoise) -> float:
    """Grasp (untimed), then time a ground-truth opening lasting OPENING_S with frames at 10 Hz."""
    grasp_handle(world, arm, panda_sim_config().motion_limits(arm.kin, 0.3), OPENING_M)
    camera = SimCamera(world, noise=noise, fps=10.0)
    v = OPENING_M / (OPENING_S - 1.0)  # cruise speed; about 1 s goes to speeding up and braking
    limits = MotionLimits(v, 2 * v, 20 * v)
    next_t = world.time

    def grab(state, _t: float) -> None:
        nonlocal next_t
        if state.t >= next_t - 1e-9:
            next_t = (camera.read().index + 1) / camera.fps

    sim0, wall0 = world.time, time.perf_counter()
    open_along_truth(world, arm, OPENING_M, limits, grab)
    return (world.time - sim0) / (time.perf_counter() - wall0)
