"""Shared pieces of the per-joint axial effects (backlash, hysteresis, nonlinear stiffness).

Each adds to joint i's axial spring twist rz (site i-1) a function of the joint's axial torque. A
gearbox's play and its soft zone sit at zero *total* torque: the static torque tau_s(q) of the arm's
weight, its balancer and the payload (`Context.static_torque`, `stiffness.statics`) plus the external
tau_i = W_i[rz] (Nm). A campaign measures loaded minus unloaded, so the deflection an effect adds is

    delta_rz = f(tau_s + tau_i) - f(tau_s)

which is f(tau_i) for a robot without masses (tau_s = 0, f(0) = 0).
"""

from __future__ import annotations

import numpy as np

from ..context import Context
from .base import Effect
from .realtime import AxialTerm


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


class AxialEffect(Effect):
    """An effect on joint i's axial twist of the form delta_rz = theta[0] * shape(tau_i; theta).

    ``axial_twist`` is the effect's equation f, in one place: the model's basis and the service's
    real-time path both call it, at the total torque (module docstring).
    """

    evidence_plot = "axial"

    def shape(self, tau, theta: np.ndarray):
        """delta_rz per unit of the linear parameter theta[0], for torque tau (Nm, scalar or array)."""
        raise NotImplementedError

    def axial_twist(self, tau, theta: np.ndarray | None = None):
        """delta_rz (rad) for joint torque tau (Nm, scalar or array)."""
        theta = self.theta if theta is None else theta
        return theta[0] * self.shape(tau, theta)

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        tau_s = ctx.static_torque[:, self.joint - 1]
        tau = tau_s + joint_torque(W, self.joint)
        return axial_basis(ctx, self.joint, [self.shape(tau, theta) - self.shape(tau_s, theta)])

    def realtime(self, robot) -> list[AxialTerm]:
        """f = `axial_twist`, the parameters frozen; the service evaluates f(tau_s + tau) - f(tau_s)."""
        theta = self.theta.copy()
        return [AxialTerm(self.joint, lambda tau: float(self.axial_twist(tau, theta)))]
