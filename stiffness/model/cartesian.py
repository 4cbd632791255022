"""Cartesian stiffness at the TCP (Eq. 1-3) and its direct identification from TCP data (Eq. 15).

Frames: the wrench W = [F, T] acts at the TCP (force in N, moment about the TCP in Nm) in base
axes; the deflection dX = [dx, dy, dz (m), rotation vector (rad)] is the TCP's, in base axes. Then
W = K dX (Eq. 1) with K = C^-1.
"""

from __future__ import annotations

import numpy as np

from ..data.measurements import Dataset
from ..kinematics.robot import BODIES
from ..kinematics.spatial import transform, transport_wrench
from .stiffness_model import StiffnessModel

TCP = BODIES.index("TCP")
UNIT = 1.0  # N or Nm per probe: small enough that the composed chain is linear to 1e-9


def tcp_compliance(model: StiffnessModel, q_deg: np.ndarray) -> np.ndarray:
    """The 6x6 compliance C (dX = C W) at the TCP for joint angles ``q_deg`` (deg).

    Evaluated by probing the model with a unit force or moment along each base axis, so it holds
    for any model that is linear in the load (for nonlinear effects it is the secant at 1 N). Each
    probe is a reading of its own at time 0: no loading history or elapsed time (hysteresis,
    drift) enters.
    """
    q_deg = np.asarray(q_deg, dtype=float).reshape(6)
    robot = model.robot
    F = robot.frames(np.radians(q_deg)[None])[0]
    T_sensor = robot.sensor_pose(F[None])[0]
    T_tcp_base_axes = transform(np.eye(3), F[7, :3, 3])
    W_tcp = np.eye(6) * UNIT
    W_sensor = transport_wrench(W_tcp, T_tcp_base_axes[None], T_sensor[None])
    data = Dataset(np.zeros(6), np.array([f"probe{k}" for k in range(6)]), np.tile(q_deg, (6, 1)), W_sensor,
                   np.full(6, TCP), np.zeros((6, 6)))
    dX = model.predict(data)
    dX[:, :3] /= 1000.0
    dX[:, 3:] = np.radians(dX[:, 3:])
    return dX.T / UNIT


MAX_CONDITION = 1e10


def tcp_stiffness(model: StiffnessModel, q_deg: np.ndarray) -> np.ndarray:
    """The Cartesian stiffness K = C^-1 at the TCP (N/m, N/rad, Nm/m, Nm/rad blocks).

    Raises ValueError where C is singular (a direction the model's springs cannot deflect, e.g. at
    a wrist singularity): K is infinite there.
    """
    C = tcp_compliance(model, q_deg)
    scale = np.r_[np.ones(3), np.full(3, 1e-3)]       # compare m/N with rad/Nm over a 1 m lever
    if np.linalg.cond(C * scale[:, None] / scale[None, :]) > MAX_CONDITION:
        raise ValueError(f"the compliance at q = {np.round(q_deg, 3).tolist()} deg is singular: the model "
                         "cannot deflect the TCP in some direction, so K is unbounded there")
    return np.linalg.inv(C)


def tcp_wrench_and_deflection(data: Dataset, model_robot) -> tuple[np.ndarray, np.ndarray]:
    """TCP rows of a campaign as (W at the TCP in base axes, dX in SI), for Eq. 15."""
    rows = data.subset(data.body == TCP)
    F = model_robot.frames(np.radians(rows.q_deg))
    T_sensor = model_robot.sensor_pose(F)
    T_tcp = transform(np.eye(3)[None].repeat(len(rows), 0), F[:, 7, :3, 3])
    W = transport_wrench(rows.wrench, T_sensor, T_tcp)
    dX = np.concatenate([rows.deflection[:, :3] / 1000.0, np.radians(rows.deflection[:, 3:])], axis=1)
    return W, dX


MIN_SPAN = 0.05      # the weakest load direction must carry this share of the strongest (physical units)
MIN_LEVER_M = 0.05   # a load lever below this (a force at the TCP) is taken as this: moments are then noise


def load_lever(W: np.ndarray) -> float:
    """The load's lever L (m): the median |M| / |F| over the rows loaded with at least 10 % of the
    largest force (a force applied at a distance L from the TCP gives |M| ~ L |F|), at least
    MIN_LEVER_M; 1 m when no row is loaded by a force."""
    F = np.linalg.norm(W[:, :3], axis=1)
    M = np.linalg.norm(W[:, 3:], axis=1)
    loaded = F > 0.1 * F.max(initial=0.0)
    if not loaded.any():
        return 1.0
    return max(float(np.median(M[loaded] / F[loaded])), MIN_LEVER_M)


def identify_cartesian(W: np.ndarray, dX: np.ndarray) -> np.ndarray:
    """Eq. 15: K^T = (sum dX dX^T)^-1 (sum dX W^T), the least-squares K with W = K dX.

    Needs loads along all six directions. Forces and moments are compared physically: a moment over
    the load's lever L (`load_lever`) is the force that makes it, so W' = [F, M / L] in N; when
    the weakest direction of W' carries less than MIN_SPAN of the strongest (e.g. every moment
    comes from forces at one fixed lever, or moments are sensor noise), K is not determined there
    (noise alone still makes dX full rank). A K whose symmetric part is not positive definite is
    no spring either. Both raise ValueError saying why.
    """
    if len(W) < 6:
        raise ValueError(f"{len(W)} TCP rows: K needs at least 6 readings loading six directions")
    lever = load_lever(W)
    s = np.linalg.svd(np.concatenate([W[:, :3], W[:, 3:] / lever], axis=1), compute_uv=False)
    if s[-1] < MIN_SPAN * s[0]:
        raise ValueError(
            f"the wrenches do not span six directions: with moments over the load's lever ({lever:.3g} m), "
            f"the weakest load direction carries {s[-1] / max(s[0], 1e-300):.2g} of the strongest (needs "
            f">= {MIN_SPAN:g}), so K cannot be identified; load the TCP along more axes, with forces at "
            "several levers or pure moments")
    M = dX.T @ dX
    K = np.linalg.solve(M, dX.T @ W).T
    eig = np.linalg.eigvalsh((K + K.T) / 2)
    if eig[0] <= 0:
        raise ValueError(f"the identified K is not positive definite (its symmetric part has eigenvalue(s) "
                         f"{', '.join(f'{e:.3g}' for e in eig[eig <= 0])}): no spring pushes back that way, "
                         "so the data do not determine K; load the TCP along more axes or measure more "
                         "repeats")
    return K
