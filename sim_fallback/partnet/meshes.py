"""The shapes of a model's links: OBJ vertices and triangles, boxes, their areas and bounds.

OBJ files are read here (vertex positions and faces only): Open3D's reader also decodes every texture an OBJ's
material names, which the geometry does not need.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from sim_fallback.partnet.errors import PartNetError
from sim_fallback.partnet.urdf import Geometry

_BOX_CORNERS = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
_BOX_TRIANGLES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                           [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])


@lru_cache(maxsize=4096)
def read_obj(path: Path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (n, 3) and triangles (m, 3, indices; polygons fanned) of an OBJ file."""
    vertices, triangles = [], []
    try:
        with open(path, errors="replace") as lines:
            for line in lines:
                if line.startswith("v "):
                    vertices.append(line.split()[1:4])
                elif line.startswith("f "):
                    corners = [int(word.split("/")[0]) for word in line.split()[1:]]
                    triangles += [(corners[0], a, b) for a, b in zip(corners[1:-1], corners[2:], strict=True)]
        v = np.array(vertices, dtype=float).reshape(-1, 3)
        t = np.array(triangles, dtype=int).reshape(-1, 3)
    except ValueError as exc:
        raise PartNetError(f"mesh {path}: not a readable OBJ ({exc}); fix: restore it from the dataset") from exc
    t = np.where(t < 0, t + len(v), t - 1)  # OBJ indices are 1-based, negative ones count from the end
    if t.size and (t.min() < 0 or t.max() >= len(v)):
        raise PartNetError(f"mesh {path}: its faces name vertices it does not have; fix: restore it from the dataset")
    return v, t


def missing_textures(objs: list[Path]) -> list[Path]:
    """The texture images (map_Kd) that the materials of the OBJ files `objs` name but that do not exist."""
    libraries = set()
    for obj in objs:
        with open(obj, errors="replace") as lines:
            libraries |= {(obj.parent / line.split(maxsplit=1)[1].strip()) for line in lines
                          if line.startswith("mtllib ") and len(line.split()) > 1}
    missing = set()
    for library in libraries:
        if library.is_file():
            for line in library.read_text(errors="replace").splitlines():
                words = line.split(maxsplit=1)
                if len(words) == 2 and words[0] == "map_Kd" and not (library.parent / words[1].strip()).is_file():
                    missing.add((library.parent / words[1].strip()).resolve())
    return sorted(missing)


def geometry_mesh(geometry: Geometry) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (in the link frame) and triangles of one visual or collision element."""
    if geometry.mesh is not None:
        v, t = read_obj(geometry.mesh)
        v = v * np.asarray(geometry.scale)
    elif geometry.box is not None:
        v, t = _BOX_CORNERS * np.asarray(geometry.box), _BOX_TRIANGLES
    else:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=int)
    return v @ geometry.T_link[:3, :3].T + geometry.T_link[:3, 3], t


def transformed(T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Points (n, 3) moved by the 4x4 transform T."""
    return points @ T[:3, :3].T + T[:3, 3]


def surface_area(vertices: np.ndarray, triangles: np.ndarray) -> float:
    """Total area of the triangles (m^2 in the vertices' unit)."""
    if not len(triangles):
        return 0.0
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    return float(0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())
