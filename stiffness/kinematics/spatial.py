"""Rigid-body helpers: rotation vectors, homogeneous transforms and wrench transport (Eq. 2-4).

All functions are batched: a leading axis of any length is carried through. Units are whatever the
caller uses consistently (the model core uses metres, radians, newtons and newton-metres).
"""

from __future__ import annotations

import numpy as np
from scipy.linalg import lapack
from scipy.spatial.transform import Rotation


def skew(v: np.ndarray) -> np.ndarray:
    """The cross-product matrix [v]x with [v]x @ w = v x w, batched over leading axes."""
    v = np.asarray(v, dtype=float)
    out = np.zeros(v.shape[:-1] + (3, 3))
    out[..., 0, 1], out[..., 0, 2] = -v[..., 2], v[..., 1]
    out[..., 1, 0], out[..., 1, 2] = v[..., 2], -v[..., 0]
    out[..., 2, 0], out[..., 2, 1] = -v[..., 1], v[..., 0]
    return out


def exp_so3(r: np.ndarray) -> np.ndarray:
    """Rotation matrices for rotation vectors ``r`` (rad), shape (..., 3) -> (..., 3, 3)."""
    r = np.asarray(r, dtype=float)
    flat = r.reshape(-1, 3)
    return Rotation.from_rotvec(flat).as_matrix().reshape(r.shape[:-1] + (3, 3))


def log_so3(R: np.ndarray) -> np.ndarray:
    """Rotation vectors (rad) of rotation matrices, shape (..., 3, 3) -> (..., 3)."""
    R = np.asarray(R, dtype=float)
    flat = R.reshape(-1, 3, 3)
    return Rotation.from_matrix(flat).as_rotvec().reshape(R.shape[:-2] + (3,))


def rpy_matrix(rpy_rad: np.ndarray) -> np.ndarray:
    """Rotation from roll-pitch-yaw angles (rad), R = Rz(yaw) Ry(pitch) Rx(roll), as URDF has it."""
    return Rotation.from_euler("xyz", rpy_rad).as_matrix()


def rot_z(t: float) -> np.ndarray:
    """The homogeneous rotation (4, 4) by ``t`` rad about z (a DH joint's turn)."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[c, -s, 0, 0], [s, c, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])


def rot_x(t: float) -> np.ndarray:
    """The homogeneous rotation (4, 4) by ``t`` rad about x (a DH twist alpha)."""
    c, s = np.cos(t), np.sin(t)
    return np.array([[1.0, 0, 0, 0], [0, c, -s, 0], [0, s, c, 0], [0, 0, 0, 1]])


def trans_z(d: float) -> np.ndarray:
    """The homogeneous translation (4, 4) by ``d`` m along z (a DH offset d)."""
    T = np.eye(4)
    T[2, 3] = d
    return T


def trans_x(a: float) -> np.ndarray:
    """The homogeneous translation (4, 4) by ``a`` m along x (a DH length a)."""
    T = np.eye(4)
    T[0, 3] = a
    return T


def transform(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    """Homogeneous 4x4 transforms from rotations (...,3,3) and translations (...,3)."""
    R = np.asarray(R, dtype=float)
    T = np.zeros(R.shape[:-2] + (4, 4))
    T[..., :3, :3] = R
    T[..., :3, 3] = p
    T[..., 3, 3] = 1.0
    return T


def twist_transform(delta: np.ndarray) -> np.ndarray:
    """The small displacement E(delta) of a spring twist delta = [x, y, z, rx, ry, rz] (m, rad).

    Translation by (x, y, z) and rotation by the rotation vector (rx, ry, rz), both in the frame the
    spring sits in (Eq. 5: the spring's displacement inserted between two links).
    """
    delta = np.asarray(delta, dtype=float)
    return transform(exp_so3(delta[..., 3:]), delta[..., :3])


def wrench_action_matrix(R_ji: np.ndarray, p_ij: np.ndarray) -> np.ndarray:
    """The matrix A of Eq. 3 mapping a wrench [F; T] given in frame i to frame j (Eq. 4).

    Parameters
    ----------
    R_ji : (..., 3, 3)
        Rotation of frame i with respect to frame j (columns: i's axes in j).
    p_ij : (..., 3)
        Position of frame j's origin in frame i, as Eq. 4 writes it (``iP_j``).

    Returns
    -------
    (..., 6, 6) matrix with  jF = jR_i iF  and  jT = jR_i (iF x iP_j + iT).
    """
    R_ji = np.asarray(R_ji, dtype=float)
    A = np.zeros(R_ji.shape[:-2] + (6, 6))
    A[..., :3, :3] = R_ji
    A[..., 3:, 3:] = R_ji
    # iF x iP_j = -[iP_j]x iF
    A[..., 3:, :3] = -R_ji @ skew(p_ij)
    return A


def transport_wrench(W_i: np.ndarray, T_0i: np.ndarray, T_0j: np.ndarray) -> np.ndarray:
    """Transport a wrench from frame i to frame j with the given (unloaded) poses, Eq. 4.

    ``W_i`` = [F, T] is the force and the moment about frame i's origin, in frame i's axes. The result
    is the same wrench as force and moment about frame j's origin, in frame j's axes.
    """
    T_ij = np.linalg.inv(T_0i) @ T_0j
    R_ji = np.swapaxes(T_ij[..., :3, :3], -1, -2)
    A = wrench_action_matrix(R_ji, T_ij[..., :3, 3])
    return np.einsum("...ab,...b->...a", A, W_i)


def damped_pinv_solve(J: np.ndarray, lam: float, rhs: np.ndarray | None = None) -> np.ndarray:
    """The damped least-squares step J^T (J J^T + λ² I)^-1 rhs (rhs = I: the damped pseudo-inverse itself).

    Parameters
    ----------
    J : (m, n) Jacobian
    lam : float
        λ, in the units of J's rows (m or rad); it bounds the step near singularities and is
        invisible (≪ the smallest singular value) away from them.
    rhs : (m,) or (m, k), optional

    One implementation for the service's correction and the HIL's inverse kinematics.
    """
    A = J @ J.T
    A.flat[:: A.shape[0] + 1] += lam * lam
    b = np.eye(A.shape[0]) if rhs is None else rhs
    return J.T @ lapack.dgesv(A, b)[2]
