"""`fit_trajectory` on handle trajectories like real recordings (`deploy bench axis --scenes paths`).

The set is `deploy.synthetic.handle_paths.handle_path_set`: 12 objects (4 drawers, 4 doors, 2 flaps on a
horizontal hinge, 2 sliding parts) opened 5 times each by a hand-like pull with pauses, tremor, play,
uneven sampling, dropped samples and tracking glitches. Each path is fitted with the joint type left to
the fit (`--joint auto`) and with it given, in the set's frame (z up, as `fit-trajectory --up z`); an
undecided answer counts as not right, never as wrong.
"""

from __future__ import annotations

import re
import time
from collections.abc import Callable

import numpy as np

from deploy.geometry.estimators.trajectory import fit_trajectory
from deploy.geometry.metrics import axis_angle_error_deg
from deploy.geometry.types import Axis
from deploy.synthetic.handle_paths import PATH_KINDS, HandlePath, handle_path_set

UP = np.array([0.0, 0.0, 1.0])
"""The set's up direction (base frame, z up)."""


def _reason_class(reason: str) -> str:
    """The failure family of an undecided answer: its reason with every figure replaced by N."""
    return re.sub(r"\d+(\.\d+)?", "N", reason.removeprefix("joint type undecided: "))


def score_path(path: HandlePath, given: bool = True) -> dict:
    """One path: the auto answer (type, angle error, reported sigma) and, with `given`, the error with the
    type given."""
    truth = path.obj.axis
    clock = time.perf_counter()
    auto = fit_trajectory(path.positions, path.quaternions, times=path.times, up=UP)
    ms = (time.perf_counter() - clock) * 1e3
    given = fit_trajectory(path.positions, path.quaternions, truth.joint_type, times=path.times, up=UP) \
        if given else None
    row = {"object": path.obj.name, "kind": path.kind, "samples": len(path.times),
           "orientations": path.quaternions is not None, "ms": ms, "type": None, "angle_deg": None,
           "sigma_deg": None, "reason": None, "given_angle_deg": None}
    if isinstance(auto, Axis):
        row.update(type=auto.joint_type.value, angle_deg=axis_angle_error_deg(truth.direction, auto.direction),
                   sigma_deg=auto.direction_sigma_deg)
    else:
        row["reason"] = auto.reason
    if isinstance(given, Axis):
        row["given_angle_deg"] = axis_angle_error_deg(truth.direction, given.direction)
    row["right"] = row["type"] == truth.joint_type.value
    return row


def _percentiles(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"median": None, "p90": None, "max": None}
    return {"median": float(np.median(values)), "p90": float(np.percentile(values, 90)), "max": float(np.max(values))}


def summarise_paths(rows: list[dict]) -> dict:
    """Joint-type counts (right / wrong / undecided and why), angle errors per kind (median, p90, max; of
    every auto answer, a wrong type included, and with the type given), every object's median (auto
    answers), and how often the error was within twice the reported sigma."""
    undecided = [r for r in rows if r["type"] is None]
    causes: dict[str, int] = {}
    for r in undecided:
        causes[_reason_class(r["reason"])] = causes.get(_reason_class(r["reason"]), 0) + 1
    kinds = {}
    for kind in PATH_KINDS:
        mine = [r for r in rows if r["kind"] == kind]
        kinds[kind] = {
            "paths": len(mine), "right": sum(r["right"] for r in mine),
            "angle_deg": _percentiles([r["angle_deg"] for r in mine if r["type"] is not None]),
            "given_angle_deg": _percentiles([r["given_angle_deg"] for r in mine if r["given_angle_deg"] is not None]),
        }
    objects = {}
    for name in dict.fromkeys(r["object"] for r in rows):
        errors = [r["angle_deg"] for r in rows if r["object"] == name and r["type"] is not None]
        objects[name] = None if not errors else float(np.median(errors))
    sized = [r for r in rows if r["right"] and r["sigma_deg"] is not None]
    return {
        "paths": len(rows),
        "joint_type_accuracy": sum(r["right"] for r in rows) / max(len(rows), 1),
        "wrong_type": sum(r["type"] is not None and not r["right"] for r in rows),
        "undecided": len(undecided),
        "undecided_causes": causes,
        "kinds": kinds,
        "object_median_angle_deg": objects,
        "within_2_sigma": None if not sized else sum(r["angle_deg"] <= 2 * r["sigma_deg"] for r in sized) / len(sized),
        "ms_median": float(np.median([r["ms"] for r in rows])) if rows else None,
    }


def bench_axis_paths(seed: int = 0, progress: Callable[[int, int], None] | None = None, given: bool = True) -> dict:
    """Score every path of the set drawn with `seed` (`score_path`); returns the `--json` dict (summary and rows)."""
    paths = handle_path_set(seed)
    rows = []
    for i, path in enumerate(paths):
        rows.append(score_path(path, given))
        if progress:
            progress(i + 1, len(paths))
    return {"seed": seed, "scenes": "paths", **summarise_paths(rows), "rows": rows}
