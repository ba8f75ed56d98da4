"""Our numpy hand-eye solvers, after the methods of OpenCV's `calibrateHandEye` (AX = XB) and
`calibrateRobotWorldHandEye` (AX = ZB). calibration.solvers uses OpenCV's and keeps these where they measure better
(`deploy bench calibration` compares both; docs/benchmarks.md): each solves the rotation first and then the
translations by linear least squares given it, where OpenCV's Andreff and Li solve both in one linear system.

Model (see calibration.hand_eye): board pose C_i = A @ M_i @ B, with M_i the known robot transform.
AX = XB methods take the motions between pairs of samples and return X = A^-1; AX = ZB methods use every
sample directly and return (A, B).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from calibration.transforms import inv

Poses = Sequence[np.ndarray]


def nearest_rotation(R: np.ndarray) -> np.ndarray:
    """The rotation matrix closest (Frobenius) to a 3x3 matrix."""
    U, _, Vt = np.linalg.svd(R)
    return U @ np.diag([1.0, 1.0, np.linalg.det(U @ Vt)]) @ Vt


def _skew(v: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def _motions(M: Poses, C: Poses) -> list[tuple[np.ndarray, np.ndarray]]:
    """Motion pairs (P, Q) with P X = X Q and X = A^-1, for every pair of samples i < j: with G_i = M_i^-1,
    G_i X C_i = B for all i, so P = G_j^-1 G_i and Q = C_j C_i^-1."""
    G = [inv(m) for m in M]  # G_i X C_i = B is the same for every i
    out = []
    for i in range(len(G)):
        for j in range(i + 1, len(G)):
            out.append((inv(G[j]) @ G[i], C[j] @ inv(C[i])))
    return out


def _translation(pairs: list[tuple[np.ndarray, np.ndarray]], R_X: np.ndarray) -> np.ndarray:
    """t_X from (R_P - I) t_X = R_X t_Q - t_P, least squares."""
    lhs = np.vstack([P[:3, :3] - np.eye(3) for P, _ in pairs])
    rhs = np.concatenate([R_X @ Q[:3, 3] - P[:3, 3] for P, Q in pairs])
    return np.linalg.lstsq(lhs, rhs, rcond=None)[0]


def _with_translation(pairs: list[tuple[np.ndarray, np.ndarray]], R_X: np.ndarray) -> np.ndarray:
    X = np.eye(4)
    X[:3, :3] = R_X
    X[:3, 3] = _translation(pairs, R_X)
    return X


def tsai(M: Poses, C: Poses) -> np.ndarray:
    """Tsai-Lenz (1989): modified Rodrigues vectors, skew(p_P + p_Q) p' = p_Q - p_P."""
    pairs = _motions(M, C)
    lhs, rhs = [], []
    for P, Q in pairs:
        p = Rotation.from_matrix(P[:3, :3]).as_rotvec()
        q = Rotation.from_matrix(Q[:3, :3]).as_rotvec()
        p = 2 * np.sin(np.linalg.norm(p) / 2) * p / max(np.linalg.norm(p), 1e-12)
        q = 2 * np.sin(np.linalg.norm(q) / 2) * q / max(np.linalg.norm(q), 1e-12)
        lhs.append(_skew(p + q))
        rhs.append(q - p)
    pc = np.linalg.lstsq(np.vstack(lhs), np.concatenate(rhs), rcond=None)[0]
    pcg = 2 * pc / np.sqrt(1 + pc @ pc)
    n2 = pcg @ pcg
    R = (1 - n2 / 2) * np.eye(3) + 0.5 * (np.outer(pcg, pcg) + np.sqrt(4 - n2) * _skew(pcg))
    return _with_translation(pairs, nearest_rotation(R))


def park(M: Poses, C: Poses) -> np.ndarray:
    """Park-Martin (1994): R_X = (N^T N)^-1/2 N^T with N = sum beta alpha^T of the motions' log rotations."""
    pairs = _motions(M, C)
    N = np.zeros((3, 3))
    for P, Q in pairs:
        N += np.outer(Rotation.from_matrix(Q[:3, :3]).as_rotvec(), Rotation.from_matrix(P[:3, :3]).as_rotvec())
    w, V = np.linalg.eigh(N.T @ N)
    R = V @ np.diag(1 / np.sqrt(np.maximum(w, 1e-18))) @ V.T @ N.T
    return _with_translation(pairs, nearest_rotation(R))


def horaud(M: Poses, C: Poses) -> np.ndarray:
    """Horaud-Dornaika (1995), rotation by unit quaternions: q_P q_X = q_X q_Q, smallest singular vector."""
    pairs = _motions(M, C)
    rows = []
    for P, Q in pairs:
        a = Rotation.from_matrix(P[:3, :3]).as_quat(scalar_first=True)
        b = Rotation.from_matrix(Q[:3, :3]).as_quat(scalar_first=True)
        rows.append(_quat_left(a) - _quat_right(b))
    q = np.linalg.svd(np.vstack(rows))[2][-1]
    return _with_translation(pairs, Rotation.from_quat(q, scalar_first=True).as_matrix())


def andreff(M: Poses, C: Poses) -> np.ndarray:
    """Andreff et al. (2001), linear Kronecker form: (R_P (x) I - I (x) R_Q^T) vec(R_X) = 0 (row-major vec)."""
    pairs = _motions(M, C)
    K = np.vstack([np.kron(P[:3, :3], np.eye(3)) - np.kron(np.eye(3), Q[:3, :3].T) for P, Q in pairs])
    R = np.linalg.svd(K)[2][-1].reshape(3, 3)
    R *= np.sign(np.linalg.det(R)) / np.cbrt(abs(np.linalg.det(R)))
    return _with_translation(pairs, nearest_rotation(R))


def shah(M: Poses, C: Poses) -> tuple[np.ndarray, np.ndarray]:
    """Shah (2013), AX = ZB by Kronecker products: R_C R_Z = R_A R_M (Z = B^-1) from the null space, then
    translations by least squares. Returns (A, B)."""
    K = np.vstack([np.hstack([np.kron(c[:3, :3], np.eye(3)), -np.kron(np.eye(3), m[:3, :3].T)])
                   for m, c in zip(M, C, strict=True)])
    v = np.linalg.svd(K)[2][-1]
    Z, A = v[:9].reshape(3, 3), v[9:].reshape(3, 3)
    scale = np.sign(np.linalg.det(A)) / np.cbrt(abs(np.linalg.det(A)))
    return _robot_world_translations(M, C, nearest_rotation(A * scale), nearest_rotation(Z * scale).T)


def li(M: Poses, C: Poses) -> tuple[np.ndarray, np.ndarray]:
    """Li et al. (2010), AX = ZB: rotations and translations of C_i Z = A M_i (Z = B^-1) in one linear least
    squares (the translation rows fix the scale), rotations projected, translations solved again.
    Returns (A, B)."""
    rows, rhs = [], []
    for m, c in zip(M, C, strict=True):
        Rc, Rm, tc, tm = c[:3, :3], m[:3, :3], c[:3, 3], m[:3, 3]
        rows.append(np.hstack([np.kron(Rc, np.eye(3)), -np.kron(np.eye(3), Rm.T), np.zeros((9, 6))]))
        rhs.append(np.zeros(9))
        rows.append(np.hstack([np.zeros((3, 9)), -np.kron(np.eye(3), tm[None, :]), Rc, -np.eye(3)]))
        rhs.append(-tc)
    v = np.linalg.lstsq(np.vstack(rows), np.concatenate(rhs), rcond=None)[0]
    return _robot_world_translations(M, C, nearest_rotation(v[9:18].reshape(3, 3)),
                                     nearest_rotation(v[:9].reshape(3, 3)).T)


def _robot_world_translations(M: Poses, C: Poses, R_A: np.ndarray, R_B: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """t_A, t_B from R_A R_M t_B + t_A = t_C - R_A t_M, least squares."""
    lhs = np.vstack([np.hstack([R_A @ m[:3, :3], np.eye(3)]) for m in M])
    rhs = np.concatenate([c[:3, 3] - R_A @ m[:3, 3] for m, c in zip(M, C, strict=True)])
    t = np.linalg.lstsq(lhs, rhs, rcond=None)[0]
    A, B = np.eye(4), np.eye(4)
    A[:3, :3], A[:3, 3] = R_A, t[3:]
    B[:3, :3], B[:3, 3] = R_B, t[:3]
    return A, B


def _quat_left(q: np.ndarray) -> np.ndarray:
    """L(q) with q p = L(q) p, scalar first."""
    w, x, y, z = q
    return np.array([[w, -x, -y, -z], [x, w, -z, y], [y, z, w, -x], [z, -y, x, w]])


def _quat_right(q: np.ndarray) -> np.ndarray:
    """R(q) with p q = R(q) p, scalar first."""
    w, x, y, z = q
    return np.array([[w, -x, -y, -z], [x, w, z, -y], [y, -z, w, x], [z, y, -x, w]])


HAND_EYE: dict[str, Callable[[Poses, Poses], np.ndarray]] = {
    "tsai": tsai, "park": park, "horaud": horaud, "andreff": andreff,
}
ROBOT_WORLD: dict[str, Callable[[Poses, Poses], tuple[np.ndarray, np.ndarray]]] = {"shah": shah, "li": li}
