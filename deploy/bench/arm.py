"""`deploy bench arm`: IK solve time and success, Ruckig calculation time, and the CAN control loop's rate and
period jitter on python-can's virtual bus with simulated Damiao motors."""

from __future__ import annotations

import time

import numpy as np

from drivers.arm.robot_config import RobotConfig
from drivers.arm.trajectory import joint_trajectory
from drivers.errors import ArmError
from sim_fallback.devices import sim_can_arm

LIMIT_MARGIN_RAD = 0.1  # random reachable poses: FK of joints drawn this far inside the limits


def bench_ik(config: RobotConfig, n: int = 500, seed: int = 0) -> dict:
    """IK to FK(q) for random q within the limits, seeded at a nearby configuration (q + N(0, 0.2 rad) per joint,
    as when following a planner's next target) and, separately, cold from the ready pose."""
    kin = config.kinematics()
    rng = np.random.default_rng(seed)
    q_ready = np.array(config.q_ready)
    out = {}
    for label, near in (("near", True), ("cold", False)):
        times, ok = [], 0
        for _ in range(n):
            q = rng.uniform(kin.q_min + LIMIT_MARGIN_RAD, kin.q_max - LIMIT_MARGIN_RAD)
            q_seed = np.clip(q + rng.normal(0.0, 0.2, q.shape), kin.q_min, kin.q_max) if near else q_ready
            T = kin.fk(q)
            t = time.perf_counter()
            try:
                kin.ik(T, q_seed, rng=rng)
                ok += 1
            except ArmError:
                pass
            times.append(time.perf_counter() - t)
        out[label] = (float(np.median(times) * 1e3), ok / n)
    return {"ik_ms_median": out["near"][0], "ik_success_rate": out["near"][1],
            "ik_cold_ms_median": out["cold"][0], "ik_cold_success_rate": out["cold"][1]}


def bench_ruckig(config: RobotConfig, n: int = 500, seed: int = 0) -> dict:
    """Offline Ruckig calculation between random joint positions (all joints, phase-synchronised)."""
    kin = config.kinematics()
    limits = config.motion_limits(kin, 0.5)
    rng = np.random.default_rng(seed)
    times = []
    for _ in range(n):
        q0, q1 = rng.uniform(kin.q_min, kin.q_max, (2, kin.dof))
        t = time.perf_counter()
        joint_trajectory(q0, q1, limits)
        times.append(time.perf_counter() - t)
    return {"ruckig_ms_median": float(np.median(times) * 1e3)}


def bench_loop(config: RobotConfig, seconds: float = 3.0, rate_hz: float = 500.0) -> dict:
    """The realtime CanArm holding position on simulated motors (their own thread) for `seconds`."""
    watchdog = config.watchdog.model_copy(update={"max_late_cycles": 1e6, "feedback_timeout_s": 10.0})
    config = config.model_copy(update={"control_rate_hz": rate_hz, "watchdog": watchdog})
    arm, _motors = sim_can_arm(config, lockstep=False)
    with arm:
        time.sleep(seconds)
        stats = arm.stats.summary(arm.control_period_s)
    return {"loop_hz": stats["loop_hz"], "loop_jitter_ms_median": stats["jitter_ms_median"],
            "loop_jitter_ms_p99": stats["jitter_ms_p99"], "motors": len(config.motors), "loop_cycles": stats["cycles"]}


def bench_arm(config: RobotConfig, n: int = 500, seconds: float = 3.0, seed: int = 0) -> dict:
    """All three; keys as documented in docs/arm.md."""
    return {**bench_ik(config, n, seed), **bench_ruckig(config, n, seed), **bench_loop(config, seconds)}
