"""What a PyBullet client shows, as ray-casting scenes: every body's visual shapes, posed each frame.

Every link's triangles are kept in the link's frame in one table (`Triangles`). Links that have not moved since
the static scene was built are merged into one Open3D `RaycastingScene` (Embree) in world coordinates, built once;
a link seen to move leaves it for good and joins the dynamic scene, rebuilt every frame from the moving links'
current poses (building a scene is cheap next to casting rays at it). A body added or removed rebuilds
everything.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d
import pybullet as pb

from sim_fallback.render.meshes import Material, Mesh, concatenate, visual_mesh

o3c = o3d.core
POSE_TOLERANCE = 1e-7  # a link whose pose changed more than this (m, or rotation-matrix entries) is moving


@dataclass(frozen=True)
class Triangles:
    """All drawn triangles: `corners` (n, 3, 3) and `normals` (n, 3) in their link's frame, `uvs` (n, 3, 2),
    `material` (n,) into `materials`, `link` (n,) into `links` ((body id, link index) pairs, -1 for a base)."""

    corners: np.ndarray
    normals: np.ndarray
    uvs: np.ndarray
    material: np.ndarray
    materials: tuple[Material, ...]
    link: np.ndarray
    links: tuple[tuple[int, int], ...]
    starts: np.ndarray  # triangles of link k: starts[k]:starts[k + 1]


@dataclass
class Hits:
    """What (n) rays met: `t` (distance in units of each ray's direction; inf where nothing), `triangle` (index
    into `Triangles`; the number of triangles where nothing), `uv` (n, 2) barycentric coordinates of the hit in its
    triangle."""

    t: np.ndarray
    triangle: np.ndarray
    uv: np.ndarray


def read_triangles(client: int) -> Triangles:
    """Every visual shape of every body of `client`, one mesh per (body, link)."""
    per_link: dict[tuple[int, int], list[Mesh]] = {}
    for i in range(pb.getNumBodies(physicsClientId=client)):
        body = pb.getBodyUniqueId(i, physicsClientId=client)
        seen = set()
        for shape in pb.getVisualShapeData(body, physicsClientId=client):
            key = (shape[1], shape[2], tuple(shape[3]), shape[4], tuple(shape[5]), tuple(shape[6]))
            if key in seen:  # PyBullet lists an OBJ once per material: draw the file once
                continue
            seen.add(key)
            mesh = visual_mesh(shape, tuple(float(c) for c in shape[7][:3]))
            if mesh is not None and len(mesh.corners):
                per_link.setdefault((body, shape[1]), []).append(mesh)
    links = tuple(per_link)
    meshes = [concatenate(per_link[k]) for k in links]
    counts = [len(m.corners) for m in meshes]
    whole = concatenate(meshes) if meshes else concatenate([])
    corners = whole.corners
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
    return Triangles(corners, normals.astype(np.float32), whole.uvs, whole.material, whole.materials,
                     np.repeat(np.arange(len(links), dtype=np.int32), counts), links,
                     np.concatenate([[0], np.cumsum(counts)]).astype(np.int64))


def link_poses(client: int, links: tuple[tuple[int, int], ...]) -> np.ndarray:
    """(n, 4, 4) world poses of the links' frames (URDF link frames; a base's frame, not its centre of mass)."""
    poses = np.tile(np.eye(4), (len(links), 1, 1))
    by_body: dict[int, list[int]] = {}
    for k, (body, _link) in enumerate(links):
        by_body.setdefault(body, []).append(k)
    for body, slots in by_body.items():
        indices = [links[k][1] for k in slots if links[k][1] >= 0]
        states = pb.getLinkStates(body, indices, computeForwardKinematics=True, physicsClientId=client) if indices \
            else []
        by_link = dict(zip(indices, states or [], strict=True))
        for k in slots:
            link = links[k][1]
            if link >= 0:
                position, quaternion = by_link[link][4], by_link[link][5]
            else:
                com_pos, com_quat = pb.getBasePositionAndOrientation(body, physicsClientId=client)
                local_pos, local_quat = pb.getDynamicsInfo(body, -1, physicsClientId=client)[3:5]
                position, quaternion = pb.multiplyTransforms(com_pos, com_quat,
                                                             *pb.invertTransform(local_pos, local_quat))
            poses[k, :3, :3] = np.reshape(pb.getMatrixFromQuaternion(quaternion), (3, 3))
            poses[k, :3, 3] = position
    return poses


def _link_boxes(tri: Triangles) -> np.ndarray:
    """(links, 8, 3) corners of each link's bounding box in its own frame."""
    boxes = np.zeros((len(tri.links), 8, 3), np.float32)
    signs = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], bool)
    for k in range(len(tri.links)):
        corners = tri.corners[tri.starts[k]:tri.starts[k + 1]].reshape(-1, 3)
        if len(corners):
            boxes[k] = np.where(signs, corners.max(axis=0), corners.min(axis=0))
    return boxes


class RayScene:
    """The triangles of a PyBullet client in two ray-casting scenes: `static` (links that have not moved since it
    was built; `version` counts its builds) and `dynamic` (the moving links, rebuilt at every `update`).

    `update()` reads the link poses (once per frame); casts then use them. Open3D runs on `threads` threads (1: the
    simulation's budget is one core).
    """

    def __init__(self, client: int, threads: int = 1) -> None:
        self.client, self.threads = client, threads
        self._bodies: tuple[int, ...] = ()
        self.version = 0
        self.update()

    def update(self) -> None:
        """Read the poses; rebuild what moved (and everything when bodies were added or removed)."""
        bodies = tuple(pb.getBodyUniqueId(i, physicsClientId=self.client)
                       for i in range(pb.getNumBodies(physicsClientId=self.client)))
        if bodies != self._bodies:
            self._bodies = bodies
            self.triangles = read_triangles(self.client)
            self._local_boxes = _link_boxes(self.triangles)
            self.poses = link_poses(self.client, self.triangles.links)
            self.moving = np.zeros(len(self.triangles.links), bool)
            self._build_static()
        else:
            self.poses = link_poses(self.client, self.triangles.links)
            moved = ~self.moving & np.any(np.abs(self.poses - self._static_poses) > POSE_TOLERANCE, axis=(1, 2))
            if moved.any():
                self.moving |= moved
                self._build_static()
        self._build_dynamic()

    def world_corners(self, ids: np.ndarray | None = None) -> np.ndarray:
        """(n, 3, 3) corners of triangles `ids` (default all) in the world at the current poses."""
        tri = self.triangles
        ids = np.arange(len(tri.link)) if ids is None else ids
        pose = self.poses[tri.link[ids]].astype(np.float32)
        return np.einsum("nij,nkj->nki", pose[:, :3, :3], tri.corners[ids]) + pose[:, None, :3, 3]

    def world_normals(self) -> np.ndarray:
        """(n, 3) triangle normals in the world at the current poses."""
        tri = self.triangles
        return np.einsum("nij,nj->ni", self.poses[tri.link, :3, :3].astype(np.float32), tri.normals)

    def _scene(self, ids: np.ndarray) -> o3d.t.geometry.RaycastingScene | None:
        if not len(ids):
            return None
        corners = np.ascontiguousarray(self.world_corners(ids).reshape(-1, 3))
        scene = o3d.t.geometry.RaycastingScene(nthreads=self.threads)
        scene.add_triangles(o3c.Tensor.from_numpy(corners),
                            o3c.Tensor.from_numpy(np.arange(len(corners), dtype=np.uint32).reshape(-1, 3)))
        return scene

    def _build_static(self) -> None:
        ids = np.flatnonzero(~self.moving[self.triangles.link])
        self._static, self._static_ids = self._scene(ids), ids
        self._static_poses = self.poses.copy()
        self.version += 1

    def _build_dynamic(self) -> None:
        ids = np.flatnonzero(self.moving[self.triangles.link])
        self._dynamic, self._dynamic_ids = self._scene(ids), ids
        links = np.flatnonzero(self.moving)
        box = self._local_boxes[links]  # (n, 8, 3) in each link's frame
        pose = self.poses[links].astype(np.float32)
        self._boxes = np.einsum("nij,nkj->nki", pose[:, :3, :3], box) + pose[:, None, :3, 3]

    def dynamic_boxes(self) -> np.ndarray:
        """(n, 8, 3) world corners of a box around each moving link (the link's bounds in its own frame)."""
        return self._boxes

    def cast(self, origin: np.ndarray, directions: np.ndarray, dynamic: bool) -> Hits:
        """Rays from `origin` (3,) along `directions` (n, 3) at the dynamic scene (else the static one): the
        nearest hit of each."""
        scene, ids = (self._dynamic, self._dynamic_ids) if dynamic else (self._static, self._static_ids)
        nothing = len(self.triangles.link)
        if scene is None or not len(directions):
            return Hits(np.full(len(directions), np.inf, np.float32), np.full(len(directions), nothing, np.int64),
                        np.zeros((len(directions), 2), np.float32))
        rays = np.empty((len(directions), 6), np.float32)
        rays[:, :3], rays[:, 3:] = origin, directions
        result = scene.cast_rays(o3c.Tensor.from_numpy(rays), nthreads=self.threads)
        rows = np.append(ids, nothing).take(np.minimum(result["primitive_ids"].numpy(), len(ids)))
        return Hits(result["t_hit"].numpy(), rows, result["primitive_uvs"].numpy())

    def occluded(self, origins: np.ndarray, directions: np.ndarray, t_far: float = np.inf, static: bool = True,
                 dynamic: bool = True) -> np.ndarray:
        """(N,) bool: whether anything (of the scenes chosen) lies on each ray `origins + t directions` for
        0 < t < `t_far`."""
        blocked = np.zeros(len(origins), bool)
        scenes = [sc for sc, use in ((self._static, static), (self._dynamic, dynamic)) if use and sc is not None]
        if not scenes or not len(origins):
            return blocked
        rays = np.empty((len(origins), 6), np.float32)
        rays[:, :3], rays[:, 3:] = origins, directions
        tensor = o3c.Tensor.from_numpy(rays)
        for scene in scenes:
            blocked |= scene.test_occlusions(tensor, tfar=t_far, nthreads=self.threads).numpy().astype(bool)
        return blocked
