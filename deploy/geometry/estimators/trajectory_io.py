"""Trajectory files: `x y z [qx qy qz qw]` per line, TUM (`timestamp tx ty tz qx qy qz qw`) and CSV with a header.

Commas, semicolons or whitespace separate values; `#` starts a comment; blank lines are skipped. Positions in
metres, quaternions xyzw (normalised here). Parse errors are ValueErrors naming the line.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

_TIME_NAMES = ("timestamp", "time", "t", "stamp", "time_s", "t_s", "sec", "seconds")
_POSITION_NAMES = (("x", "y", "z"), ("tx", "ty", "tz"), ("px", "py", "pz"), ("pos_x", "pos_y", "pos_z"),
                   ("position_x", "position_y", "position_z"), ("x_m", "y_m", "z_m"))
_QUATERNION_NAMES = (("qx", "qy", "qz", "qw"), ("quat_x", "quat_y", "quat_z", "quat_w"),
                     ("orientation_x", "orientation_y", "orientation_z", "orientation_w"),
                     ("rot_x", "rot_y", "rot_z", "rot_w"))
_FORMATS = {3: "xyz", 7: "xyz+quaternion", 8: "tum"}
_DEFAULT_COLUMNS = {3: {"position": [0, 1, 2]}, 7: {"position": [0, 1, 2], "quaternion": [3, 4, 5, 6]},
                    8: {"time": [0], "position": [1, 2, 3], "quaternion": [4, 5, 6, 7]}}


@dataclass(frozen=True)
class Trajectory:
    """Samples of a file: positions (N,3) m, unit quaternions (N,4) xyzw or None, times (N,) s or None
    (as in the file, not sorted), and the format read ("xyz", "xyz+quaternion", "tum" or "csv")."""

    positions: np.ndarray
    quaternions: np.ndarray | None
    times: np.ndarray | None
    format: str


def _fields(line: str) -> list[str]:
    """The values of a line: split at commas or semicolons when it has them (a header name may hold
    spaces), else at whitespace."""
    separator = "," if "," in line else ";" if ";" in line else None
    parts = line.split(separator) if separator else line.split()
    return [f.strip() for f in parts if f.strip()]


def _number(field: str) -> bool:
    try:
        float(field)
    except ValueError:
        return False
    return True


def _normalise(name: str) -> str:
    """Header name without units or brackets, lower case: 'Pos X [m]' -> 'pos_x'."""
    name = re.sub(r"[\[(].*?[\])]", "", name.strip().lstrip("#").lower()).strip()
    return re.sub(r"[\s.\-/]+", "_", name).strip("_")


def _columns(header: list[str], number: int) -> dict[str, list[int]]:
    """Column indices of 'time', 'position' and 'quaternion' in a CSV header (line `number`)."""
    names = [_normalise(h) for h in header]
    found: dict[str, list[int]] = {}
    for key, options in (("position", _POSITION_NAMES), ("quaternion", _QUATERNION_NAMES)):
        for option in options:
            if all(n in names for n in option):
                found[key] = [names.index(n) for n in option]
                break
    time = [names.index(n) for n in _TIME_NAMES if n in names]
    if time:
        found["time"] = time[:1]
    if "position" not in found:
        raise ValueError(
            f"trajectory line {number}: header {', '.join(header)} names no position columns; "
            "name them x,y,z (or tx,ty,tz / px,py,pz), optionally with qx,qy,qz,qw and timestamp")
    return found


def _row(fields: list[str], number: int, raw: str) -> list[float]:
    try:
        values = [float(f) for f in fields]
    except ValueError:
        raise ValueError(f"trajectory line {number}: not a number in {raw.strip()!r}") from None
    if not np.all(np.isfinite(values)):
        raise ValueError(f"trajectory line {number}: NaN or inf in {raw.strip()!r}")
    return values


def parse_trajectory(text: str) -> Trajectory:
    """The samples of a trajectory file's text (module docstring). Without a header, the value count
    of the first line decides: 3 (x y z), 7 (x y z qx qy qz qw) or 8 (TUM); every line must match it."""
    rows: list[list[float]] = []
    columns: dict[str, list[int]] | None = None
    width, kind = None, "xyz"
    for number, raw in enumerate(text.splitlines(), start=1):
        fields = _fields(raw.split("#", 1)[0].strip())
        if not fields:
            continue
        if width is None and not any(_number(f) for f in fields):
            columns, width, kind = _columns(fields, number), len(fields), "csv"
            continue
        if kind != "csv" and len(fields) not in _FORMATS:
            raise ValueError(
                f"trajectory line {number}: expected 3 values (x y z), 7 (x y z qx qy qz qw) or 8 (TUM: "
                f"timestamp tx ty tz qx qy qz qw), got {len(fields)}: {raw.strip()!r}")
        if width is None:
            width, kind, columns = len(fields), _FORMATS[len(fields)], _DEFAULT_COLUMNS[len(fields)]
        if len(fields) != width:
            what = "earlier lines have" if kind != "csv" else "the header has"
            raise ValueError(
                f"trajectory line {number}: {len(fields)} values but {what} {width}; "
                "use the same format (with or without quaternions) on every line")
        values = _row(fields, number, raw)
        if "quaternion" in columns and np.linalg.norm([values[i] for i in columns["quaternion"]]) < 1e-9:
            raise ValueError(f"trajectory line {number}: zero quaternion in {raw.strip()!r}")
        rows.append(values)
    return _assemble(rows, columns or {}, kind)


def _assemble(rows: list[list[float]], columns: dict[str, list[int]], kind: str) -> Trajectory:
    if not rows:
        return Trajectory(np.zeros((0, 3)), None, None, kind)
    data = np.array(rows)
    quaternions = None
    if "quaternion" in columns:
        quaternions = data[:, columns["quaternion"]]
        quaternions = quaternions / np.linalg.norm(quaternions, axis=1, keepdims=True)
    times = data[:, columns["time"][0]] if "time" in columns else None
    return Trajectory(data[:, columns["position"]], quaternions, times, kind)


def parse_trajectory_text(text: str) -> tuple[np.ndarray, np.ndarray | None]:
    """Positions (N,3) and unit quaternions (N,4) or None of a trajectory file's text, in time order
    when the file has timestamps (`parse_trajectory`)."""
    trajectory = parse_trajectory(text)
    if trajectory.times is None:
        return trajectory.positions, trajectory.quaternions
    order = np.argsort(trajectory.times, kind="stable")
    quaternions = None if trajectory.quaternions is None else trajectory.quaternions[order]
    return trajectory.positions[order], quaternions
