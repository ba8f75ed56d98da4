"""Small objects in the PartNet-Mobility layout, made by the tests (no dataset file is used).

An object is a cabinet of boxes: a body, a drawer over a door (or the fronts given), each front with a bar handle
(its own "handle" sub-part), a push button on top; modelled as the dataset models them: y up, the front on a chosen
model axis, normalised to about 2 units across, links `link_N` with meshes under `textured_objs/` (OBJ + MTL + a PNG
texture under `images/`), the root joint turning the model z up, and a non-unit prismatic axis.

Geometry is given in the object's own front frame ("front" coordinates): x out of the front, y to the object's left,
z up, origin at the body's centre.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from PIL import Image

BODY = np.array([0.8, 1.0, 1.2])  # depth (x), width (y), height (z) in model units
PANEL = 0.02
FRONT_X = BODY[0] / 2 + PANEL  # the fronts' outer face
MODEL_AXES = {  # columns: the front frame's x (front), y (left), z (up) in model coordinates (y up)
    "+z": np.array([[0, 0, 1], [1, 0, 0], [0, 1, 0]], dtype=float).T,
    "+x": np.array([[1, 0, 0], [0, 0, -1], [0, 1, 0]], dtype=float).T,
    "-x": np.array([[-1, 0, 0], [0, 0, 1], [0, 1, 0]], dtype=float).T,
}
ROOT_RPY = "1.570796326794897 0 -1.570796326794897"  # the dataset's base -> body joint: model y up -> z up


@dataclass(frozen=True)
class Front:
    """A drawer or door front covering `y` x `z` (front coordinates); a door hinges on its low-y edge,
    `hinge_depth` behind its outer face. `handle`: "bar" (horizontal on drawers, vertical on doors) or None;
    `label` as semantics.txt says it; `inset`: how far behind the fronts' outer face it stands (inside the body)."""

    kind: str
    y: tuple[float, float]
    z: tuple[float, float]
    handle: str | None = "bar"
    label: str = ""
    hinge_depth: float = 0.0
    inset: float = 0.0

    def grip_centre(self) -> np.ndarray:
        """Where the handle's bar centre is, front coordinates (closed)."""
        y = (self.y[0] + self.y[1]) / 2 if self.kind == "drawer" else self.y[1] - 0.08
        return np.array([FRONT_X + BAR_STANDOFF, y, (self.z[0] + self.z[1]) / 2])


BAR_LENGTH, BAR_THICKNESS, BAR_STANDOFF = 0.3, 0.03, 0.05  # the bar's centre line stands this far out
DRAWER_TRAVEL = 0.6  # a drawer's range (model units)
DRAWER_OVER_DOOR = (Front("drawer", (-0.48, 0.48), (0.25, 0.58), label="drawer"),
                    Front("door", (-0.48, 0.48), (-0.58, 0.23), label="rotation_door"))


def write_object(folder: Path, front_axis: str = "+z", fronts: tuple[Front, ...] = DRAWER_OVER_DOOR,
                 category: str = "StorageFurniture", drawer_open: float = 0.0, axis_length: float = 0.1) -> Path:
    """Write one object into `folder` (created) and return it. `drawer_open`: how far out the drawers are
    modelled (their joints' lower limit, closed, is -drawer_open); `axis_length`: the prismatic axes' length
    as written."""
    M = MODEL_AXES[front_axis]
    writer = _Writer(folder, M)
    body = [((-BODY[0] / 2 + PANEL / 2, 0, 0), (PANEL, BODY[1], BODY[2]))]  # back
    body += [((0, s * (BODY[1] / 2 - PANEL / 2), 0), (BODY[0], PANEL, BODY[2])) for s in (-1, 1)]  # sides
    body += [((0, 0, s * (BODY[2] / 2 - PANEL / 2)), (BODY[0], BODY[1], PANEL)) for s in (-1, 1)]  # top, bottom
    links = [writer.link("link_0", [("frame", body)])]
    joints = [f'<joint name="joint_0" type="fixed"><origin rpy="{ROOT_RPY}" xyz="0 0 0"/>'
              f'<child link="link_0"/><parent link="base"/></joint>']
    semantics = ["link_0 heavy furniture_body"]
    parts = [{"id": 0, "parent": -1, "joint": "heavy", "name": "frame", "parts": [{"id": 100, "name": "frame"}],
              "jointData": {}}]
    for n, front in enumerate(fronts, start=1):
        link, joint, subparts = _front_link(writer, n, front, drawer_open, axis_length)
        links.append(link)
        joints.append(joint)
        semantics.append(f"link_{n} {'slider' if front.kind == 'drawer' else 'hinge'} {front.label or front.kind}")
        parts.append({"id": n, "parent": 0, "joint": "slider" if front.kind == "drawer" else "hinge",
                      "name": front.kind, "parts": subparts, "jointData": {}})
    button = len(fronts) + 1
    links.append(writer.link(f"link_{button}", [("button", [((0.2, 0.3, BODY[2] / 2 + 0.01), (0.04, 0.04, 0.02))])],
                             origin=(0.2, 0.3, BODY[2] / 2)))
    joints.append(_joint(f"joint_{button}", "prismatic", f"link_{button}", M @ (0.2, 0.3, BODY[2] / 2),
                         M @ (0, 0, -1.0), 0.0, 0.01))
    semantics.append(f"link_{button} slider button")
    parts.append({"id": button, "parent": 0, "joint": "slider", "name": "button", "parts": [], "jointData": {}})
    (folder / "mobility.urdf").write_text('<?xml version="1.0" ?>\n<robot name="test_object">\n<link name="base"/>\n'
                                          + "\n".join(links + joints) + "\n</robot>\n")
    (folder / "semantics.txt").write_text("\n".join(semantics) + "\n")
    (folder / "mobility_v2.json").write_text(json.dumps(parts))
    (folder / "meta.json").write_text(json.dumps({"anno_id": folder.name, "model_cat": category}))
    return folder


def _front_link(writer: _Writer, n: int, front: Front, drawer_open: float, axis_length: float):
    """The link, joint and mobility_v2 sub-parts of one front (sub-part ids 10n: the panel, 10n+1: the handle)."""
    M = writer.M
    (y0, y1), (z0, z1) = front.y, front.z
    shift = np.array([(drawer_open if front.kind == "drawer" else 0.0) - front.inset, 0, 0])  # as modelled
    pieces = [(f"{front.kind}_front-{10 * n}", [((FRONT_X - PANEL / 2, (y0 + y1) / 2, (z0 + z1) / 2),
                                                 (PANEL, y1 - y0, z1 - z0))])]
    if front.kind == "drawer":
        depth = BODY[0] - 2 * PANEL
        pieces.append((f"drawer_bottom-{10 * n + 2}",
                       [((FRONT_X - PANEL - depth / 2, (y0 + y1) / 2, z0 + 0.02), (depth, y1 - y0 - 0.04, PANEL))]))
    subparts = [{"id": 10 * n, "name": f"{front.kind}_front"}]
    if front.handle:
        pieces.append((f"handle-{10 * n + 1}", _bar(front)))
        subparts.append({"id": 10 * n + 1, "name": "handle"})
    pieces = [(name, [(tuple(np.add(centre, shift)), size) for centre, size in boxes]) for name, boxes in pieces]
    if front.kind == "drawer":
        origin = np.array([FRONT_X, (y0 + y1) / 2, (z0 + z1) / 2]) + shift
        joint = _joint(f"joint_{n}", "prismatic", f"link_{n}", M @ origin, axis_length * (M @ (1.0, 0, 0)),
                       -drawer_open, DRAWER_TRAVEL - drawer_open)
    else:
        origin = np.array([FRONT_X - front.hinge_depth, y0, (z0 + z1) / 2])
        joint = _joint(f"joint_{n}", "revolute", f"link_{n}", M @ origin, M @ (0, 0, -1.0), 0.0, np.pi / 2)
    return writer.link(f"link_{n}", pieces, origin=origin), joint, subparts


def _bar(front: Front) -> list:
    """A bar on two posts (one OBJ, like a dataset handle): horizontal on a drawer, vertical on a door."""
    c = front.grip_centre()
    along = np.array([0, 1.0, 0]) if front.kind == "drawer" else np.array([0, 0, 1.0])
    across = np.array([0, 1.0, 0]) if front.kind == "door" else np.array([0, 0, 1.0])
    out = np.array([1.0, 0, 0])
    post_depth = c[0] - BAR_THICKNESS / 2 - FRONT_X
    bar = (tuple(c), tuple(BAR_THICKNESS * (out + across) + BAR_LENGTH * along))
    posts = [(tuple(out * (FRONT_X + post_depth / 2) + c * (along + across) + s * along * (BAR_LENGTH / 2 - 0.02)),
              tuple(out * post_depth + 0.015 * (along + across))) for s in (-1, 1)]
    return [bar, *posts]


def _joint(name: str, kind: str, child: str, origin, axis, lower: float, upper: float) -> str:
    return (f'<joint name="{name}" type="{kind}"><origin xyz="{_xyz(origin)}"/><axis xyz="{_xyz(axis)}"/>'
            f'<child link="{child}"/><parent link="link_0"/><limit lower="{lower}" upper="{upper}"/></joint>')


class _Writer:
    """Writes a link's boxes as textured OBJ files (one per piece) under the object's textured_objs/."""

    def __init__(self, folder: Path, M: np.ndarray) -> None:
        self.folder, self.M, self.count = folder, M, 0
        (folder / "textured_objs").mkdir(parents=True, exist_ok=True)
        (folder / "images").mkdir(exist_ok=True)
        pixels = (np.indices((8, 8)).sum(axis=0) % 2 * 120 + 80).astype(np.uint8)
        Image.fromarray(np.stack([pixels, pixels // 2, pixels // 3], axis=-1)).save(folder / "images" / "texture_0.png")

    def link(self, name: str, pieces: list, origin=(0.0, 0.0, 0.0)) -> str:
        """A link whose frame sits at `origin` (front coordinates); its meshes are written in model coordinates
        and placed with the visual origin -origin, as the dataset does."""
        offset = _xyz(-(self.M @ np.asarray(origin, dtype=float)))
        elements = []
        for piece_name, boxes in pieces:
            mesh = self._obj(boxes)
            geometry = f'<origin xyz="{offset}"/><geometry><mesh filename="textured_objs/{mesh}"/></geometry>'
            elements.append(f'<visual name="{piece_name}">{geometry}</visual><collision>{geometry}</collision>')
        return f'<link name="{name}">{"".join(elements)}</link>'

    def _obj(self, boxes: list) -> str:
        stem = f"original-{self.count}"
        self.count += 1
        lines = [f"mtllib {stem}.mtl", f"o {stem}", "vt 0 0", "vt 1 0", "vt 1 1", "vt 0 1", "usemtl m0"]
        corners = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
        quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
        for k, (centre, size) in enumerate(boxes):
            for v in corners * size + centre:
                lines.append(f"v {_xyz(self.M @ v)}")
            lines += [f"f {' '.join(f'{8 * k + i + 1}/{j + 1}' for j, i in enumerate(q))}" for q in quads]
        (self.folder / "textured_objs" / f"{stem}.obj").write_text("\n".join(lines) + "\n")
        (self.folder / "textured_objs" / f"{stem}.mtl").write_text(
            "newmtl m0\nKd 1 1 1\nmap_Kd ../images/texture_0.png\n")
        return f"{stem}.obj"


def _xyz(v) -> str:
    return " ".join(f"{float(x):.9g}" for x in v)
