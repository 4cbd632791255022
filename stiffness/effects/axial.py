"""Shared pieces of the per-joint axial effects (backlash, hysteresis, nonlinear stiffness).

Each adds to joint i's axial spring twist rz (site i-1) a function of the joint's axial torque. A
gearbox's play and its soft zone sit at zero *total* torque: the static torque tau_s(q) of the arm's
weight, its balancer and the payload (`Context.static_torque`, `stiffness.kinematics.statics`) plus the external
tau_i = W_i[rz] (Nm). A campaign measures loaded minus unloaded, so the deflection an effect adds is

    delta_rz = f(tau_s + tau_i) - f(tau_s)

which is f(tau_i) for a robot without masses (tau_s = 0, f(0) = 0).

The diagnosis also tries each of these effects with its centre free per configuration
(`with_free_centres`): tau_s found where each configuration's residual steps (`stiffness.model.preload_term`),
for a preload the model does not know (masses wrong or missing).
"""

from __future__ import annotations

import copy

import numpy as np

from ..data import crossings
from ..data.campaign import Context
from .base import Effect
from .terms import AxialTerm


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

    The equation is written once, as the module-level ``law(tau, p)`` of the effect's own file (a plain
    numeric function, `stiffness.effects.terms`), with ``p = law_params(theta)``; ``shape`` and the
    service's real-time path (Python and compiled) all call it, at the total torque (module docstring).
    """

    law = None          # law(tau, p) -> delta_rz (rad): a staticmethod of the subclass, or set per instance

    def law_params(self, theta: np.ndarray) -> np.ndarray:
        """The law's parameter array p for the effect's parameters ``theta`` (SI)."""
        raise NotImplementedError

    evidence_plot = "axial"
    free_centres: np.ndarray | None = None     # (C,) tau_s per configuration found by the diagnosis, NaN: beyond
    centres_found: np.ndarray | None = None    # (C,) bool: where the step was found

    def shape(self, tau, theta: np.ndarray):
        """delta_rz per unit of the linear parameter theta[0], for torque tau (Nm, scalar or array)."""
        p = self.law_params(theta).copy()
        p[0] = 1.0
        return self.law(tau, p)

    def axial_twist(self, tau, theta: np.ndarray | None = None):
        """delta_rz (rad) for joint torque tau (Nm, scalar or array)."""
        theta = self.theta if theta is None else theta
        return theta[0] * self.shape(tau, theta)

    def static_torque(self, ctx: Context) -> np.ndarray:
        """tau_s (R,) at this joint: the model's, or the free centres the diagnosis found."""
        if self.free_centres is None:
            return ctx.static_torque[:, self.joint - 1]
        return np.nan_to_num(self.free_centres, nan=crossings.FAR_NM)[ctx.config]

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        tau_s = self.static_torque(ctx)
        tau = tau_s + joint_torque(W, self.joint)
        return axial_basis(ctx, self.joint, [self.shape(tau, theta) - self.shape(tau_s, theta)])

    def centre_text(self, model, ctx: Context) -> str:
        """For a variant with free centres: where each configuration crosses it, and that its centre moves
        away from the model's static torque (the masses are wrong or missing); else ''."""
        if self.free_centres is None:
            return ""
        found = np.where(self.centres_found, self.free_centres, np.nan)
        held = [(lab, -v) for lab, v, ok in
                zip(ctx.config_labels, crossings.centres(model, ctx, self.joint), self.centres_found) if ok]
        if all(abs(x) < 0.5 for _, x in held):
            where = "away from zero external torque, where a model without static torque puts it"
        else:
            where = "away from where the model's static torque puts it (external " + crossings.and_join(
                [f"{x:+.0f} Nm in {lab}" for lab, x in held]) + ")"
        return (f" at zero total torque: {crossings.crossing_text(ctx, self.joint, found)}. Its centre moves from "
                f"one configuration to the next, {where}: the masses are wrong or missing. Add it with its "
                "preload identified (`stiffcomp model add MODEL EFFECT --joint J --preload identify`, docs/effects.md)")

    def realtime(self, robot) -> list[AxialTerm]:
        """The law with its parameters frozen; the service evaluates f(tau_s + tau) - f(tau_s)."""
        return [AxialTerm(self.joint, law=self.law, params=self.law_params(self.theta))]


def with_free_centres(model, ctx: Context, variants: list[AxialEffect]) -> list[AxialEffect]:
    """Copies of ``variants`` with their centre free per configuration, where the fitted ``model``'s residual
    shows a step in at least two configurations away from where the model puts it (`crossings.centre_search`);
    none when it does not."""
    key = ("fitted_residual", id(model))
    if key not in ctx.cache:
        resid = ctx.data.deflection - model.predict(ctx)
        sigma = np.array([model.noise["position_mm"]] * 3 + [model.noise["rotation_deg"]] * 3)
        ctx.cache[key] = (resid, sigma)
    resid, sigma = ctx.cache[key]
    out = []
    for e in variants:
        theta = e.theta.copy()
        centres, found = crossings.centre_search(ctx, resid, sigma, e.joint,
                                                 lambda t, e=e, theta=theta: e.shape(t, theta))
        if found.sum() < 2:
            continue
        held = crossings.centres(model, ctx, e.joint)
        moved = np.abs(centres[found] - held[found])
        if not np.any(moved > 0.05 * torque_range(ctx, e.joint)):
            continue
        free = copy.copy(e)
        free.free_centres, free.centres_found = centres, found
        out.append(free)
    return out
