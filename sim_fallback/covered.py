"""Parts hidden behind another part's front: a hand reaching the closed furniture from outside meets the other part
first, so no pull opens them (a cabinet's drawers standing inside it, behind its closed door).

Pure geometry on `PartGeometry` (furniture frame: x out of the front, closed parts' boxes)."""

from __future__ import annotations

import numpy as np

from sim_fallback.furniture_body import PartGeometry

AHEAD_M = 0.01  # a covering part's box reaches at least this far out beyond the hidden part's ...
COVERED_SHARE = 0.5  # ... over more than this share of the hidden part's front (seen along x)


def covering_part(part: PartGeometry, geometry: list[PartGeometry]) -> str | None:
    """The name of the part standing in front of `part` as seen from outside the furniture (along -x): its box
    reaches AHEAD_M beyond `part`'s box and, seen along x, covers more than COVERED_SHARE of `part`'s front; None
    when no part does. Neighbouring fronts in one plane, overlapping at their edges or by a handle, cover none."""
    lo, hi = part.box
    area = float(np.prod(hi[1:] - lo[1:]))
    for other in geometry:
        other_lo, other_hi = other.box
        if other.name == part.name or other_hi[0] < hi[0] + AHEAD_M:
            continue
        shared = np.clip(np.minimum(hi[1:], other_hi[1:]) - np.maximum(lo[1:], other_lo[1:]), 0.0, None)
        if float(np.prod(shared)) > COVERED_SHARE * area:
            return other.name
    return None
