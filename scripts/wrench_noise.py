"""Noise of the tool wrench estimated from joint torques (drivers/arm/wrench.py) on the simulated arms: the sim arm
with PyBullet's exact torques, the sim arm with its torques measured as Damiao motors measure them
(sim_fallback/torque_sensing.py, as every episode's arm has), and the CAN driver over simulated motors (sim-can).

Per drawer scene of the test split: 2 s holding still (the second one counted), then 12 cm out and back at 8 cm/s
without contact, then the handle grasped (the scripted grasp, ground truth) and pulled 15 cm along the true axis,
compliant and force-bounded as an episode pulls. Force magnitude (N), filtered (the robot config's low-pass) and raw.
Holding still: |F| as the torques read (a motor-current offset reads as a force); the torques' offset is then
measured over that second, as an episode does at its pre-grasp pose, and subtracted from then on: moving, |F|;
pulling, what the controller acts on, |F - F at the pull's start|. The first 10 % of each phase is dropped. `std` is
the spread within a scene (the mean over the scenes), the rest pool the scenes' samples.

    OPENBLAS_NUM_THREADS=1 .venv/bin/python scripts/wrench_noise.py  # JSON: mean, median, std, p90, max per phase
"""

from __future__ import annotations

import json

import numpy as np

from drivers.arm.motion import follow_cartesian_path, line_path
from drivers.arm.registry import open_arm
from drivers.arm.robot_config import load_robot_config
from drivers.arm.trajectory import MotionLimits
from drivers.arm.wrench import WrenchEstimator, torque_offset
from sim_fallback.arm import SimArm
from sim_fallback.scenario import Scenario
from sim_fallback.scripted import grasp_handle
from sim_fallback.world import SimWorld

PANDA = load_robot_config("panda_sim")
KINDS = ("sim exact", "sim", "sim-can")
SCENES = range(3)
STILL_TICKS = 480
MOVE_M, PULL_M, LIMITS = 0.12, 0.15, MotionLimits(0.08, 0.32, 3.2)
COMPLIANCE = PANDA.compliance.gains().with_force_limit(60.0)


def stats(scenes: list[list[float]]) -> dict[str, float]:
    a = np.concatenate(scenes)
    return {"mean": float(a.mean()), "median": float(np.median(a)), "std": float(np.mean([np.std(x) for x in scenes])),
            "p90": float(np.percentile(a, 90)), "max": float(a.max())}


def record(kind: str, seed: int) -> dict[str, tuple[list[float], list[float]]]:
    """(filtered, raw) force magnitudes per phase on one drawer scene of the test split."""
    with SimWorld(Scenario.make("drawer", seed, "test")) as world:
        arm = SimArm(world, PANDA.kinematics()) if kind == "sim exact" else open_arm(kind, PANDA, world=world)
        with arm:
            filtered = WrenchEstimator(arm.kin, PANDA.compliance.filter_time_constant_s)
            raw = WrenchEstimator(arm.kin, 0.0)
            rec: dict[str, tuple[list[float], list[float]]] = {"still": ([], []), "moving": ([], []),
                                                                "pulling": ([], [])}
            start = [np.zeros(3), np.zeros(3)]

            def note(phase: str, state) -> None:
                filtered.update(state)
                raw.update(state)
                rec[phase][0].append(float(np.linalg.norm(filtered.force - start[0])))
                rec[phase][1].append(float(np.linalg.norm(raw.force - start[1])))

            still = []
            for k in range(STILL_TICKS):
                arm.sync()
                filtered.update(arm.state())
                if k >= STILL_TICKS // 2:  # settled from the world's start
                    still.append(arm.state())
                    note("still", still[-1])
            offset = torque_offset(arm.kin, still)
            filtered.offset = raw.offset = offset
            here = arm.kin.fk(arm.state().q)[:3, 3]
            back = -here * np.array([1.0, 1.0, 0.0])
            back = back / np.linalg.norm(back) + [0.0, 0.0, 0.5]  # toward the robot base, and up
            for direction in (back, -back):
                follow_cartesian_path(arm, arm.kin, line_path(arm.kin.fk(arm.state().q), direction), MOVE_M, LIMITS,
                                      lambda state, _t: note("moving", state))
            grasp_handle(world, arm, MotionLimits.for_robot(world.robot_spec, arm.kin, 0.3), PULL_M)
            for estimator in (filtered, raw):
                estimator.update(arm.state())
            start[:] = [filtered.force, raw.force]
            follow_cartesian_path(arm, arm.kin, line_path(arm.kin.fk(arm.state().q), world.truth().direction),
                                  PULL_M, LIMITS, lambda state, _t: note("pulling", state),
                                  compliance=COMPLIANCE.with_torque_offset(offset))
    return {phase: (f[len(f) // 10:], r[len(r) // 10:]) for phase, (f, r) in rec.items()}


def main() -> None:
    out: dict[str, dict[str, list[list[float]]]] = {}
    for kind in KINDS:
        for seed in SCENES:
            for phase, (f, r) in record(kind, seed).items():
                entry = out.setdefault(f"{kind} {phase}", {"filtered": [], "raw": []})
                entry["filtered"].append(f)
                entry["raw"].append(r)
    print(json.dumps({k: {kk: stats(vv) for kk, vv in v.items()} for k, v in out.items()}, indent=1))


if __name__ == "__main__":
    main()
