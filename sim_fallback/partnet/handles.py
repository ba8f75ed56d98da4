"""A part's handle (ground truth) from the model's handle meshes: where a gripper holds it and which way."""

from __future__ import annotations

import numpy as np

from sim_fallback.furniture import Handle

KNOB_ASPECT = 1.5  # a handle whose length is under this many times its width on the front is a knob
LONG_BAR_M = 0.30  # bars at least this long are long bars
RECESSED_M = 0.005  # a handle standing out of the part's front by less than this is recessed in it


def handle_truth(handle: np.ndarray, front: np.ndarray, normal: np.ndarray, up: np.ndarray) -> Handle:
    """The handle whose surface points are `handle` (n, 3; metres, any frame), on a part whose other points are
    `front`, facing `normal` (unit, out of the part's front) with `up` (unit) vertical; all in one frame.

    The grip centre is the middle of the handle's extent on the front, half its width (at most half its
    depth) inside its outermost point; `axis` runs along its longer extent on the front (vertical for a knob).
    """
    up = up - (up @ normal) * normal
    up /= np.linalg.norm(up)
    lateral = np.cross(up, normal)
    basis = np.stack([normal, lateral, up])
    h = handle @ basis.T
    lo, hi = h.min(axis=0), h.max(axis=0)
    depth, width, height = hi - lo
    length, thickness = max(width, height), min(width, height)
    knob = length < KNOB_ASPECT * thickness
    axis = up if knob or height >= width else lateral
    centre_n = hi[0] - min(thickness, depth) / 2
    centre = np.array([centre_n, (lo[1] + hi[1]) / 2, (lo[2] + hi[2]) / 2]) @ basis
    protrusion = hi[0] - float((front @ normal).max()) if len(front) else depth
    if protrusion < RECESSED_M:
        style = "recessed"
    elif knob:
        style = "knob"
    else:
        style = "long-bar" if length >= LONG_BAR_M else "bar"
    return Handle(style=style, centre=_tuple(centre), axis=_tuple(axis), normal=_tuple(normal),
                  length_m=float(length), thickness_m=float(thickness))


def handle_in_link(handle: Handle, R_link: np.ndarray, t_link: np.ndarray) -> Handle:
    """`handle` moved from the frame it was given in to a link's frame, the link's pose in that frame being
    (`R_link`, `t_link`)."""
    def direction(v) -> tuple[float, float, float]:
        return _tuple(R_link.T @ np.asarray(v))

    return Handle(style=handle.style, centre=_tuple(R_link.T @ (np.asarray(handle.centre) - t_link)),
                  axis=direction(handle.axis), normal=direction(handle.normal), length_m=handle.length_m,
                  thickness_m=handle.thickness_m)


def _tuple(v) -> tuple[float, float, float]:
    return tuple(round(float(x), 9) for x in v)
