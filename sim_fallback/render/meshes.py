"""Triangle meshes of PyBullet's visual shapes, in their link's frame: boxes, cylinders, spheres, capsules,
planes and OBJ meshes with their MTL materials (Kd colour, map_Kd texture, UVs), as PyBullet reports them
(`pb.getVisualShapeData`).

A mesh is a triangle soup: `corners` (n, 3, 3) float32 metres, `uvs` (n, 3, 2) texture coordinates (0 where a
triangle has none) and `material` (n,) indices into `materials`. OBJ files are parsed once per process (keyed by
path, size and modification time); scale and placement are applied per use.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import cv2
import numpy as np
import pybullet as pb

log = logging.getLogger(__name__)

CYLINDER_SEGMENTS = 24  # around a cylinder, capsule or sphere
SPHERE_RINGS = 12
PLANE_HALF_M = 50.0  # PyBullet's planes are infinite: drawn as a square this far out


@dataclass(frozen=True)
class Material:
    """A surface's colour (linear RGB 0-1) and, for textured meshes, its texture image file (None: plain)."""

    rgb: tuple[float, float, float]
    texture: Path | None = None


@dataclass(frozen=True)
class Mesh:
    """A triangle soup with per-triangle materials (see the module docstring)."""

    corners: np.ndarray
    uvs: np.ndarray
    material: np.ndarray
    materials: tuple[Material, ...]

    def transformed(self, scale: np.ndarray, T: np.ndarray) -> Mesh:
        """The mesh scaled per axis, then moved by the 4x4 `T`."""
        corners = (self.corners * np.asarray(scale, np.float32)) @ T[:3, :3].T.astype(np.float32)
        return Mesh(corners + T[:3, 3].astype(np.float32), self.uvs, self.material, self.materials)


def concatenate(meshes: list[Mesh]) -> Mesh:
    """One mesh holding all of `meshes` (materials renumbered)."""
    offsets = np.cumsum([0] + [len(m.materials) for m in meshes])
    return Mesh(np.concatenate([m.corners for m in meshes]).reshape(-1, 3, 3).astype(np.float32),
                np.concatenate([m.uvs for m in meshes]).reshape(-1, 3, 2).astype(np.float32),
                np.concatenate([m.material + o for m, o in zip(meshes, offsets, strict=False)]).astype(np.int32),
                tuple(mat for m in meshes for mat in m.materials))


def _plain(corners: np.ndarray, rgb: tuple[float, float, float]) -> Mesh:
    n = len(corners)
    return Mesh(np.asarray(corners, np.float32).reshape(n, 3, 3), np.zeros((n, 3, 2), np.float32),
                np.zeros(n, np.int32), (Material(rgb),))


def box(half: np.ndarray, rgb: tuple[float, float, float]) -> Mesh:
    """An axis-aligned box of half extents `half` centred at the origin, outward-wound."""
    signs = np.array([[(i >> 2) & 1, (i >> 1) & 1, i & 1] for i in range(8)]) * 2 - 1
    v = signs * np.asarray(half, float)
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    tris = [(a, b, c) for a, b, c, d in faces] + [(a, c, d) for a, b, c, d in faces]
    return _plain(v[np.array(tris)], rgb)


def _revolved(profile: np.ndarray, rgb: tuple[float, float, float]) -> Mesh:
    """The surface swept by (radius, z) `profile` points about z (a closed body when its ends have radius 0)."""
    a = np.linspace(0.0, 2 * math.pi, CYLINDER_SEGMENTS + 1)
    ring = np.stack([np.cos(a), np.sin(a)], -1)
    points = np.array([[[r * c, r * s, z] for c, s in ring] for r, z in profile])  # (rings, segments + 1, 3)
    p00, p01, p10, p11 = points[:-1, :-1], points[:-1, 1:], points[1:, :-1], points[1:, 1:]
    corners = np.concatenate([np.stack([p00, p01, p11], -2), np.stack([p00, p11, p10], -2)]).reshape(-1, 3, 3)
    area = np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    return _plain(corners[area > 1e-12], rgb)


def cylinder(radius: float, length: float, rgb: tuple[float, float, float]) -> Mesh:
    """A closed cylinder along z, centred at the origin."""
    h = length / 2
    return _revolved(np.array([[0.0, -h], [radius, -h], [radius, h], [0.0, h]]), rgb)


def sphere(radius: float, rgb: tuple[float, float, float], half_length: float = 0.0) -> Mesh:
    """A sphere of `radius` at the origin; with `half_length` a capsule along z (its cylinder that long x 2)."""
    polar = np.linspace(0.0, math.pi, SPHERE_RINGS + 1)
    lower = [[radius * math.sin(p), -half_length - radius * math.cos(p)] for p in polar[: SPHERE_RINGS // 2 + 1]]
    upper = [[radius * math.sin(p), half_length - radius * math.cos(p)] for p in polar[SPHERE_RINGS // 2:]]
    return _revolved(np.array(lower + upper), rgb)


def plane(rgb: tuple[float, float, float]) -> Mesh:
    """The z = 0 plane (normal +z), as a large square."""
    s = PLANE_HALF_M
    v = np.array([[-s, -s, 0.0], [s, -s, 0.0], [s, s, 0.0], [-s, s, 0.0]])
    return _plain(v[[[0, 1, 2], [0, 2, 3]]], rgb)


def visual_mesh(shape: tuple, rgb: tuple[float, float, float]) -> Mesh | None:
    """The mesh of one `pb.getVisualShapeData` entry in its link's frame; None for a shape that cannot be drawn
    (a mesh given to PyBullet as arrays rather than a file)."""
    kind, dims, filename = shape[2], shape[3], shape[4].decode()
    T = np.eye(4)
    T[:3, :3] = np.reshape(pb.getMatrixFromQuaternion(shape[6]), (3, 3))
    T[:3, 3] = shape[5]
    if kind == pb.GEOM_BOX:
        mesh = box(np.asarray(dims) / 2, rgb)
    elif kind == pb.GEOM_CYLINDER:
        mesh = cylinder(dims[1], dims[0], rgb)
    elif kind == pb.GEOM_CAPSULE:
        mesh = sphere(dims[1], rgb, dims[0] / 2)
    elif kind == pb.GEOM_SPHERE:
        mesh = sphere(dims[0], rgb)
    elif kind == pb.GEOM_PLANE:
        mesh = plane(rgb)
    elif kind == pb.GEOM_MESH and filename and Path(filename).is_file():
        loaded = read_obj(Path(filename)) if filename.lower().endswith(".obj") else read_other(Path(filename))
        return tinted(loaded, rgb).transformed(np.asarray(dims), T)
    else:
        log.warning("the simulated camera cannot draw body %d link %d's visual shape (geometry type %d, %s): "
                    "skipped; give meshes as OBJ, STL or PLY files", shape[0], shape[1], kind,
                    filename or "given as arrays")
        return None
    return mesh.transformed(np.ones(3), T)


def tinted(mesh: Mesh, rgb: tuple[float, float, float]) -> Mesh:
    """`mesh` with its materials' colours multiplied by `rgb` (PyBullet's rgbaColor of the visual)."""
    if rgb == (1.0, 1.0, 1.0):
        return mesh
    mats = tuple(Material(tuple(float(a * b) for a, b in zip(m.rgb, rgb, strict=True)), m.texture)
                 for m in mesh.materials)
    return Mesh(mesh.corners, mesh.uvs, mesh.material, mats)


def read_obj(path: Path) -> Mesh:
    """The OBJ file at `path` with its MTL materials (cached per file version)."""
    stat = path.stat()
    return _read_obj(path.resolve(), stat.st_size, stat.st_mtime_ns)


def read_other(path: Path) -> Mesh:
    """A mesh file other than OBJ (STL, PLY, ...), through Open3D, in one plain white material."""
    import open3d as o3d

    mesh = o3d.io.read_triangle_mesh(str(path))
    v, t = np.asarray(mesh.vertices), np.asarray(mesh.triangles)
    return _plain(v[t], (1.0, 1.0, 1.0))


@lru_cache(maxsize=512)
def _read_obj(path: Path, _size: int, _mtime_ns: int) -> Mesh:
    vertices, texcoords, faces, tex_faces, face_material = [], [], [], [], []
    names: dict[str, int] = {}
    library: dict[str, Material] = {}
    current = names.setdefault("", 0)
    for line in path.read_text(errors="replace").splitlines():
        key, _, rest = line.strip().partition(" ")
        if key == "v":
            vertices.append([float(x) for x in rest.split()[:3]])
        elif key == "vt":
            texcoords.append([float(x) for x in rest.split()[:2]])
        elif key == "f":
            refs = [r.split("/") for r in rest.split()]
            v = [_index(r[0], len(vertices)) for r in refs]
            t = [_index(r[1], len(texcoords)) if len(r) > 1 and r[1] else -1 for r in refs]
            for k in range(1, len(v) - 1):  # a fan over a polygon
                faces.append((v[0], v[k], v[k + 1]))
                tex_faces.append((t[0], t[k], t[k + 1]))
                face_material.append(current)
        elif key == "usemtl":
            current = names.setdefault(rest.strip(), len(names))
        elif key == "mtllib":
            library.update(_read_mtl(path.parent / rest.strip()))
    if not faces:
        return _plain(np.zeros((0, 3, 3)), (1.0, 1.0, 1.0))
    corners = np.asarray(vertices, np.float32)[np.asarray(faces)]
    tex = np.asarray(tex_faces)
    uvs = np.zeros((len(faces), 3, 2), np.float32)
    if texcoords:
        has = np.all(tex >= 0, axis=1)
        uvs[has] = np.asarray(texcoords, np.float32)[tex[has]]
    materials = tuple(library.get(name, Material((1.0, 1.0, 1.0))) for name in names)
    return Mesh(corners, uvs, np.asarray(face_material, np.int32), materials)


def _index(token: str, count: int) -> int:
    i = int(token)
    return i - 1 if i > 0 else count + i


def _read_mtl(path: Path) -> dict[str, Material]:
    """Materials of an MTL file: Kd and map_Kd (a missing file or texture leaves the colour alone)."""
    if not path.is_file():
        log.warning("material library %s is missing: its materials are drawn white", path)
        return {}
    found: dict[str, dict] = {}
    name = None
    for line in path.read_text(errors="replace").splitlines():
        key, _, rest = line.strip().partition(" ")
        if key == "newmtl":
            name = rest.strip()
            found[name] = {"rgb": (1.0, 1.0, 1.0), "texture": None}
        elif name is not None and key == "Kd":
            found[name]["rgb"] = tuple(float(x) for x in rest.split()[:3])
        elif name is not None and key == "map_Kd":
            texture = path.parent / rest.split()[-1]
            found[name]["texture"] = texture if texture.is_file() else None
    return {k: Material(v["rgb"], v["texture"]) for k, v in found.items()}


@lru_cache(maxsize=64)
def texture_image(path: Path) -> np.ndarray:
    """A texture image as linear RGB float32 (H, W, 3), row 0 at v = 1 (OBJ's v runs up)."""
    image = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if image is None:
        log.warning("texture %s cannot be read: drawn grey", path)
        return np.full((1, 1, 3), 0.5, np.float32)
    return srgb_to_linear(cv2.cvtColor(image, cv2.COLOR_BGR2RGB))


def srgb_to_linear(image: np.ndarray) -> np.ndarray:
    """8-bit sRGB to linear float32."""
    x = np.arange(256, dtype=np.float64) / 255
    table = np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4).astype(np.float32)
    return table[image]
