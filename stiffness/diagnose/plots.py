"""Figures of the diagnosis: where the residual lives, and the evidence for the named effect."""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..data.campaign import Context
from ..data.residuals import axial_residual
from ..report.plots import legend_below
from ..units import RAD_TO_DEG


def axial_residual_vs_torque(ctx: Context, resid: np.ndarray, sigma: np.ndarray,
                             highlight: int | None = None) -> Figure:
    """Per joint, the unexplained axial rotation of each reading against the joint's torque.

    A step at zero torque is backlash, two branches by loading direction are hysteresis, an S-shape
    is a stiffness that changes with torque; a cloud around zero is noise.
    """
    fig = Figure(figsize=(12, 6.5), layout="constrained")
    axes = fig.subplots(2, 3)
    for j, ax in zip(range(1, 7), axes.ravel()):
        s = axial_residual(ctx, resid, sigma, j) * RAD_TO_DEG
        tau = ctx.frame_wrench[:, j - 1, 5]
        ax.axhline(0, color="0.6", lw=0.8)
        ax.axvline(0, color="0.6", lw=0.8)
        ax.plot(tau, s, ".", ms=3, color="C3" if j == highlight else "C0", alpha=0.6)
        ax.set_title(f"joint {j}" + ("  (named)" if j == highlight else ""))
        ax.set_xlabel(f"joint {j} torque τ{j} (Nm)")
        ax.set_ylabel("unexplained axial rotation (deg)")
    fig.suptitle("Residual as each joint's axial rotation, against that joint's torque")
    return fig


def residual_vs_time(ctx: Context, resid: np.ndarray) -> Figure:
    """TCP (or the most distal measured body) residual against time within each configuration."""
    fig = Figure(figsize=(12, 3.8), layout="constrained")
    axes = fig.subplots(1, 2)
    body = ctx.body.max()
    m = ctx.body == body
    t = ctx.rows(ctx.t_rel)[m]
    cfg = ctx.rows(ctx.config)[m]
    for k, (ax, sl, unit) in enumerate(zip(axes, (slice(0, 3), slice(3, 6)), ("mm", "deg"))):
        for c in np.unique(cfg):
            mc = cfg == c
            ax.plot(t[mc], np.linalg.norm(resid[m][mc, sl], axis=1), ".", ms=3,
                    label=ctx.config_labels[c])
        ax.set_xlabel("time since the configuration's first reading (s)")
        ax.set_ylabel(f"|residual| ({unit})")
    legend_below(fig, axes[0], ncols=12, markerscale=3)
    fig.suptitle("Residual of the most distal body against time")
    return fig


def residual_vs_force(ctx: Context, resid: np.ndarray) -> Figure:
    """Residual components of the most distal body against the sensor-frame force."""
    fig = Figure(figsize=(12, 6), layout="constrained")
    axes = fig.subplots(2, 3)
    body = ctx.body.max()
    m = ctx.body == body
    f = ctx.rows(ctx.wrench_sensor)[m]
    labels = ("dx (mm)", "dy (mm)", "dz (mm)", "rx (deg)", "ry (deg)", "rz (deg)")
    for k, ax in enumerate(axes.ravel()):
        for a in range(3):
            ax.plot(f[:, a], resid[m][:, k], ".", ms=2, alpha=0.5, label=f"f{'xyz'[a]}")
        ax.set_ylabel(f"residual {labels[k]}")
        ax.set_xlabel("sensor force (N)")
    legend_below(fig, axes[0, 0], markerscale=4)
    fig.suptitle("Residual of the most distal body against the sensor-frame force")
    return fig


def evidence(candidate, ctx: Context, resid: np.ndarray, sigma: np.ndarray) -> Figure:
    """The evidence plot for a candidate, of the kind its effect names (`Effect.evidence_plot`): for a
    joint's axial effect, its unexplained axial rotation against torque with the fitted curve (coloured
    by the loading branch for "axial_branches"); otherwise the residual against the deflection the
    effect predicts (points on the diagonal: the effect explains them)."""
    e = candidate.effect
    fig = Figure(figsize=(7.5, 5), layout="constrained")
    ax = fig.subplots()
    if e.evidence_plot in ("axial", "axial_branches"):
        j = e.joint
        s = axial_residual(ctx, resid, sigma, j) * RAD_TO_DEG
        fit = axial_residual(ctx, candidate.contribution, sigma, j) * RAD_TO_DEG
        offset = _total_offset(e, ctx)
        tau = ctx.frame_wrench[:, j - 1, 5] + offset                        # the total torque
        order = np.argsort(tau)
        if getattr(e, "free_centres", None) is not None:                 # one colour per configuration
            for c, label in enumerate(ctx.config_labels):
                mk = ctx.config == c
                beyond = "" if e.centres_found[c] else " (not crossed: beyond its load range)"
                ax.plot(tau[mk], s[mk], ".", ms=4, label=f"residual, {label}{beyond}")
        elif e.evidence_plot == "axial_branches":
            z = e.loading(ctx, ctx.frame_wrench, e.theta)
            for mk, lab, col in ((z > 0.5, "torque rising", "C0"), (z < -0.5, "torque falling", "C1"),
                                 (np.abs(z) <= 0.5, "between branches", "0.5")):
                ax.plot(tau[mk], s[mk], ".", color=col, ms=4, label=f"residual, {lab}")
        else:
            ax.plot(tau, s, ".", ms=4, label="residual (each reading)")
        mark = "k" if getattr(e, "free_centres", None) is not None else "C3"     # off the configurations' colours
        ax.plot(tau[order], fit[order], "x", color=mark, ms=4, label=f"{e.name} fitted (each reading)")
        ax.set_xlabel(f"joint {j} total torque τs + τ{j} (Nm)" if np.any(offset) else f"joint {j} torque (Nm)")
        ax.set_ylabel(f"unexplained axial rotation of joint {j} (deg)")
    else:
        pred = candidate.contribution / sigma
        r = resid / sigma
        ax.plot(pred.ravel(), r.ravel(), ".", ms=2, alpha=0.4, label="residual entries (noise units)")
        lim = np.abs(pred).max() * 1.1 or 1.0
        ax.plot([-lim, lim], [-lim, lim], color="C3", label="explained exactly")
        ax.set_xlabel(f"deflection {e.name} predicts (noise units)")
        ax.set_ylabel("residual (noise units)")
    ax.axhline(0, color="0.6", lw=0.8)
    legend_below(fig, ax, markerscale=3, ncols=3 if getattr(e, "free_centres", None) is not None else None)
    where = f" at {e.location_key} {e.joint}" if e.joint is not None else ""
    ax.set_title(f"Evidence: {e.name}{where}")
    return fig


def _total_offset(e, ctx: Context) -> np.ndarray | float:
    """tau_s per reading at the effect's joint: its free centres where found, else the model's."""
    if not hasattr(e, "static_torque"):
        return 0.0
    if getattr(e, "free_centres", None) is None:
        return e.static_torque(ctx)
    held = ctx.static_torque[:, e.joint - 1]
    return np.where(e.centres_found[ctx.config], e.free_centres[ctx.config], held)
