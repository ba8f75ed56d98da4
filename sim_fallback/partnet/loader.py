"""A PartNet-Mobility object as a `Furniture`: its drawers and doors (model.py says which links they are), its pose
in the furniture frame and its size as real furniture (or its own), and the URDF copy PyBullet loads."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path
from typing import Literal

import numpy as np

from sim_fallback.furniture import Furniture, Mechanism, Part, PartKind
from sim_fallback.partnet.errors import PartNetError
from sim_fallback.partnet.frame import (
    footprint_pose,
    front_direction,
    furniture_rotation,
    nearest_horizontal_axis,
    swept,
)
from sim_fallback.partnet.handles import handle_in_link, handle_truth
from sim_fallback.partnet.meshes import geometry_mesh
from sim_fallback.partnet.model import PartNetModel
from sim_fallback.partnet.naming import grid_positions, part_names
from sim_fallback.partnet.sizes import real_scale
from sim_fallback.worlds import SCALES

ScaleRule = Literal["real", "native"]
SCALE_RULES: tuple[ScaleRule, ...] = tuple(SCALES)  # type: ignore[assignment]
MECHANISMS: dict[PartKind, Mechanism] = {  # the middle of the procedural cabinets' ranges (cabinet_urdf.py)
    "drawer": Mechanism(friction=8.0, damping=5.0),
    "door": Mechanism(friction=1.0, damping=1.0),
}
FITTING_GAP_M = 0.003  # what a fitter leaves between a unit and its neighbours or the counter over it
DOOR_SWING_RAD = np.pi / 2  # a door is given room to open this far (its range, when less)
BEFORE_FRONT_M = 0.03  # swung parts this far before the front still meet a neighbour (its handles stand out)
BOARD_KG_PER_M2 = 10.0  # a link's mass per m^2 of its bounding box's three faces (15 mm board, ~680 kg/m^3)


def load_partnet(folder: Path, part: str | None = None, scale: ScaleRule = "real") -> Furniture:
    """The object in `folder` (one PartNet-Mobility object: mobility.urdf, semantics.txt ...) as furniture.

    scale: "real" sizes it as a real piece of its category (sizes.py); "native" keeps the model's own units as
    metres (what the paper and RGBManip load). part: when given, a part name or link name the object must have.
    Parts come drawers first, then doors, each top to bottom then left to right as someone facing them sees them.
    """
    if scale not in SCALE_RULES:
        raise PartNetError(f"scale {scale!r}: unknown; fix: use one of {', '.join(SCALE_RULES)}")
    model = PartNetModel(Path(folder))
    if not model.openable:
        raise PartNetError(f"{model.source}: no drawer or door part ({model.semantics_text()}); fix: choose an "
                           f"object with a slider drawer or a hinged door")
    R = _rotation(model)
    body = model.body_points()
    s = 1.0 if scale == "native" else real_scale(footprint_pose(R, body, 1.0)[1], model.files.category)
    T_urdf, body_size = footprint_pose(R, body, s)
    side, top = _swing_room(model, T_urdf, s, body_size)
    width, depth, height = body_size
    size = (width + 2 * (side + FITTING_GAP_M), depth, height + top + FITTING_GAP_M)
    parts = tuple(part for kind in ("drawer", "door") for part in _parts(model, kind, R, s))
    furniture = Furniture(urdf=_write_copy(model, s), T_urdf=T_urdf, scale=s, size_m=tuple(map(float, size)),
                          parts=parts, source=model.source)
    if part is not None:
        try:
            furniture.part(part)
        except KeyError:
            listed = ", ".join(f"{p.name} ({p.link})" for p in parts)
            raise PartNetError(f"{model.source} has no part {part!r}: it has {listed}; fix: name one of these "
                               f"(or its link)") from None
    return furniture


def _rotation(model: PartNetModel) -> np.ndarray:
    """3x3: the root frame's vectors in the furniture frame (x the front, z the model's up)."""
    axes = model.model_axes()
    try:
        front = front_direction([model.opening_direction(p.link) for p in model.openable], axes, axes[:, 1])
    except ValueError:
        raise PartNetError(f"{model.source}: none of its drawers and doors opens sideways or forward, so its front "
                           f"is unknown; fix: choose another object") from None
    return furniture_rotation(front, axes[:, 1])


def _swing_room(model: PartNetModel, T_urdf: np.ndarray, s: float, body_size: np.ndarray) -> tuple[float, float]:
    """How far its drawers and doors, moved through their range (a door up to a right angle), reach past the
    body's sides and top (m) behind the front and just before it, where a unit beside it or a counter over it
    stands: a door whose hinge sits inside its edge swings its edge sideways. A kitchen leaves it that much more
    room. `T_urdf`, `s` and `body_size` as `footprint_pose` gives them (the body centred on the furniture frame's
    origin, on the floor, its front at x = depth / 2)."""
    width, depth, height = body_size
    side = top = 0.0
    for part in model.openable:
        joint, T = model.urdf.joints[part.link], model.poses[part.link]
        upper = joint.upper if joint.type == "prismatic" else min(joint.upper, DOOR_SWING_RAD)
        moved = swept(model.part_points(part.link), joint.type, T[:3, :3] @ joint.axis, T[:3, 3], upper)
        moved = s * moved @ T_urdf[:3, :3].T + T_urdf[:3, 3]
        moved = moved[moved[:, 0] <= depth / 2 + BEFORE_FRONT_M]
        if len(moved):
            side = max(side, float(np.abs(moved[:, 1]).max() - width / 2))
            top = max(top, float(moved[:, 2].max() - height))
    return side, top


def _parts(model: PartNetModel, kind: PartKind, R: np.ndarray, s: float) -> list[Part]:
    """The parts of one kind, named and ordered by where they sit on the front, with ranges and handles (in
    their link frames) at scale `s`."""
    links = [p.link for p in model.openable if p.kind == kind]
    spans = []
    for link in links:
        y, z = (R @ model.part_points(link).T * s)[1:]
        spans.append((y.min(), y.max(), z.min(), z.max()))
    positions = grid_positions(np.array(spans))
    order = sorted(range(len(links)), key=lambda i: positions[i])
    parts = []
    for name, i in zip(part_names(kind, [positions[i] for i in order]), order, strict=True):
        joint = model.urdf.joints[links[i]]
        upper = joint.upper * s if joint.type == "prismatic" else joint.upper
        parts.append(Part(name=name, kind=kind, link=links[i], joint=joint.name, upper=float(upper),
                          handle=_handle(model, links[i], R, s), mechanism=MECHANISMS[kind]))
    return parts


def _handle(model: PartNetModel, link: str, R: np.ndarray, s: float):
    """A part's handle truth in its link frame at scale `s` (None when the model has no handle for it)."""
    handle = model.handle_points(link)
    if handle is None:
        return None
    axes = model.model_axes()
    normal = R @ nearest_horizontal_axis(model.opening_direction(link), axes, axes[:, 1])
    truth = handle_truth(handle @ R.T * s, model.part_points(link) @ R.T * s, normal, np.array([0.0, 0.0, 1.0]))
    T = model.poses[link]
    return handle_in_link(truth, R @ T[:3, :3], s * R @ T[:3, 3])


def _inertials(model: PartNetModel, s: float) -> dict[str, tuple[float, np.ndarray, np.ndarray]]:
    """Each link's mass (BOARD_KG_PER_M2), centre (model units) and box moments from its meshes' bounds at
    scale `s`."""
    inertials = {}
    for link, visuals in model.urdf.visuals.items():
        found = [geometry_mesh(v)[0] for v in visuals]
        points = np.concatenate(found) * s if found else np.zeros((1, 3))
        lo, hi = points.min(axis=0), points.max(axis=0)
        a, b, c = np.maximum(hi - lo, 1e-3)
        mass = max(BOARD_KG_PER_M2 * (a * b + b * c + a * c), 0.01)
        moments = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
        inertials[link] = (mass, (lo + hi) / 2 / s, moments)
    return inertials


def _write_copy(model: PartNetModel, s: float) -> Path:
    """The URDF copy PyBullet loads, in the user's cache ($XDG_CACHE_HOME/axisloop/partnet), named by its
    content (written once, renamed into place so parallel workers never read half a file)."""
    text = model.urdf.pybullet_text(_inertials(model, s))
    digest = hashlib.sha1(text.encode()).hexdigest()[:12]
    cache = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "axisloop" / "partnet"
    path = cache / f"{model.files.object_id}_{digest}.urdf"
    if not path.exists():
        cache.mkdir(parents=True, exist_ok=True)
        partial = path.with_name(f"{path.stem}.{os.getpid()}.urdf")
        partial.write_text(text)
        os.replace(partial, path)
    return path
