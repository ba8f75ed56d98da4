"""Noise of the tool wrench estimated from joint torques (drivers/arm/wrench.py), on the simulated arm and on the
simulated CAN arm: force magnitude (N) while holding still for 1 s, then moving 12 cm out and back at 8 cm/s
without contact, filtered (the robot config's low-pass) and raw. The first 10 % of each phase is dropped.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/wrench_noise.py   # JSON: mean, std, p90, max per phase
"""

from __future__ import annotations

import json

import numpy as np

from drivers.arm.motion import follow_cartesian_path, line_path
from drivers.arm.registry import open_arm
from drivers.arm.robot_config import load_robot_config
from drivers.arm.trajectory import MotionLimits
from drivers.arm.wrench import WrenchEstimator
from sim_fallback.arm import SimArm
from sim_fallback.scenario import Scenario
from sim_fallback.world import SimWorld

PANDA = load_robot_config("panda_sim")
STILL_TICKS = 240
MOVE_M, LIMITS = 0.12, MotionLimits(0.08, 0.32, 3.2)


def stats(x: list[float]) -> dict[str, float]:
    a = np.asarray(x)
    return {"mean": float(a.mean()), "std": float(a.std()), "p90": float(np.percentile(a, 90)), "max": float(a.max())}


def record(kind: str, seed: int) -> dict[str, tuple[list[float], list[float]]]:
    """(filtered, raw) force magnitudes per phase on one drawer scene of the test split."""
    with SimWorld(Scenario.make("drawer", seed, "test")) as world:
        arm = SimArm(world, PANDA.kinematics()) if kind == "sim" else open_arm("sim-can", PANDA, world=world)
        with arm:
            filtered = WrenchEstimator(arm.kin, PANDA.compliance.filter_time_constant_s)
            raw = WrenchEstimator(arm.kin, 0.0)
            rec: dict[str, tuple[list[float], list[float]]] = {"still": ([], []), "moving": ([], [])}

            def note(phase: str, state) -> None:
                filtered.update(state)
                raw.update(state)
                rec[phase][0].append(filtered.force_n)
                rec[phase][1].append(raw.force_n)

            for _ in range(STILL_TICKS):
                arm.sync()
                note("still", arm.state())
            start = arm.kin.fk(arm.state().q)[:3, 3]
            back = -start * np.array([1.0, 1.0, 0.0])
            back = back / np.linalg.norm(back) + [0.0, 0.0, 0.5]  # toward the robot base, and up
            for direction in (back, -back):
                follow_cartesian_path(arm, arm.kin, line_path(arm.kin.fk(arm.state().q), direction), MOVE_M, LIMITS,
                                      lambda state, _t: note("moving", state))
    return {phase: (f[len(f) // 10:], r[len(r) // 10:]) for phase, (f, r) in rec.items()}


def main() -> None:
    out: dict[str, dict[str, list[float]]] = {}
    for kind in ("sim", "sim-can"):
        for seed in range(3):
            for phase, (f, r) in record(kind, seed).items():
                entry = out.setdefault(f"{kind} {phase}", {"filtered": [], "raw": []})
                entry["filtered"] += f
                entry["raw"] += r
    print(json.dumps({k: {kk: stats(vv) for kk, vv in v.items()} for k, v in out.items()}, indent=1))


if __name__ == "__main__":
    main()
