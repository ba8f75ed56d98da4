"""Names of a unit's parts as a user says them ("top drawer", "left door", "second left drawer"), from where they
sit on the front as someone facing it sees them."""

from __future__ import annotations

import numpy as np

_ORDINALS = ("second", "third", "fourth", "fifth", "sixth", "seventh", "eighth", "ninth")


def grid_positions(spans: np.ndarray) -> list[tuple[int, int]]:
    """(row, column) of each part from `spans` (n, 4): lateral low/high and vertical low/high, lateral growing
    to the viewer's right. Rows count from the top and columns from the viewer's left; a part shares a row
    (column) with the first part of it whose vertical (lateral) span holds its centre."""
    spans = np.asarray(spans, dtype=float).reshape(-1, 4)
    rows = _groups(-(spans[:, 2] + spans[:, 3]) / 2, -spans[:, 3], -spans[:, 2])
    columns = _groups((spans[:, 0] + spans[:, 1]) / 2, spans[:, 0], spans[:, 1])
    return list(zip(rows, columns, strict=True))


def part_names(kind: str, positions: list[tuple[int, int]]) -> list[str]:
    """Names of the parts of one `kind` at grid `positions`; a position's word is left out where all parts
    share it, and parts in one cell are numbered ("drawer", "drawer 2")."""
    rows = sorted({r for r, _ in positions})
    columns = sorted({c for _, c in positions})
    names, seen = [], {}
    for r, c in positions:
        words = [_row_word(rows.index(r), len(rows)), _column_word(columns.index(c), len(columns)), kind]
        name = " ".join(w for w in words if w)
        seen[name] = seen.get(name, 0) + 1
        names.append(name if seen[name] == 1 else f"{name} {seen[name]}")
    return names


def _groups(centres: np.ndarray, low: np.ndarray, high: np.ndarray) -> list[int]:
    """Group index of each item along one direction, groups numbered in increasing `centres`."""
    group = [-1] * len(centres)
    count = 0
    for i in np.argsort(centres, kind="stable"):
        if group[i] >= 0:
            continue
        for j in np.argsort(centres, kind="stable"):
            if group[j] < 0 and low[i] <= centres[j] <= high[i]:
                group[j] = count
        count += 1
    return group


def _row_word(index: int, count: int) -> str:
    if count == 1:
        return ""
    if index == 0:
        return "top"
    if index == count - 1:
        return "bottom"
    if count == 3:
        return "middle"
    return _ORDINALS[index - 1] if index - 1 < len(_ORDINALS) else f"row {index + 1}"


def _column_word(index: int, count: int) -> str:
    if count == 1:
        return ""
    if count <= 3:
        return ("left", "middle", "right")[index] if count == 3 else ("left", "right")[index]
    return f"column {index + 1}"
