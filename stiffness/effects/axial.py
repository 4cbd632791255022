"""Shared pieces of the per-joint axial effects (backlash, hysteresis, nonlinear stiffness).

Each adds to joint i's axial spring twist rz (site i-1) a function of the joint's axial torque
tau_i = W_i[rz], the external moment about joint i's axis (Nm).
"""

from __future__ import annotations

import numpy as np

from ..context import Context
from .base import Effect


def joint_torque(W: np.ndarray, joint: int) -> np.ndarray:
    """tau_i (R,): the moment about joint i's axis, from the frame wrenches W (R, 7, 6)."""
    return W[:, joint - 1, 5]


def axial_basis(ctx: Context, joint: int, columns: list[np.ndarray]) -> np.ndarray:
    """Basis (R, P, 12, 6) with each column an axial twist (rad per parameter unit) at joint i."""
    B = Effect.zeros(ctx, len(columns))
    for p, col in enumerate(columns):
        B[:, p, joint - 1, 5] = col
    return B


def torque_range(ctx: Context, joint: int) -> float:
    """The largest |tau_i| in the campaign (Nm), at least 1 Nm."""
    return max(float(np.abs(joint_torque(ctx.frame_wrench, joint)).max(initial=0.0)), 1.0)
