"""Where a model fails: residual statistics, the noise from repeated readings, and residual patterns.

All functions take the residual (N, 6) = measured - predicted in [mm, mm, mm, deg, deg, deg].
"""

from __future__ import annotations

import numpy as np

from ..kinematics.robot import BODIES
from .campaign import Context
from .measurements import COMPONENTS

LOAD_BINS = 4
MIN_PURE_ERROR_DOF = 200
MIN_NOISE_MM, MIN_NOISE_DEG = 1e-6, 1e-8   # below these the repeats are noise-free, not measured


def normalised_rms(resid: np.ndarray, sigma: np.ndarray, mask: np.ndarray | None = None) -> float:
    r = (resid if mask is None else resid[mask]) / sigma
    r = r[np.isfinite(r)]
    return float(np.sqrt(np.mean(r**2))) if r.size else float("nan")


def worst(ctx: Context, resid: np.ndarray, sigma: np.ndarray) -> dict:
    """The body, component, configuration and load range with the largest noise-normalised RMS."""
    data = ctx.data
    body_scores = {BODIES[b]: normalised_rms(resid, sigma, data.body == b) for b in np.unique(data.body)}
    comp_scores = {c: normalised_rms(resid[:, k], sigma[k]) for k, c in enumerate(COMPONENTS)}
    cfg_scores = {c: normalised_rms(resid, sigma, data.config == c) for c in data.configs}
    fmag = np.linalg.norm(data.wrench[:, :3], axis=1)
    edges = np.linspace(0, max(fmag.max(), 1e-9), LOAD_BINS + 1)
    load_scores = {}
    for k in range(LOAD_BINS):
        m = (fmag >= edges[k]) & ((fmag < edges[k + 1]) | (k == LOAD_BINS - 1))
        if m.any():
            load_scores[f"{edges[k]:.0f}-{edges[k + 1]:.0f} N"] = normalised_rms(resid, sigma, m)
    pick = lambda d: max(d, key=lambda k: -np.inf if np.isnan(d[k]) else d[k])
    return {"body": pick(body_scores), "component": pick(comp_scores), "config": pick(cfg_scores),
            "load_range": pick(load_scores), "scores": {"body": body_scores, "component": comp_scores,
                                                       "config": cfg_scores, "load_range": load_scores}}


def repeat_groups(ctx: Context, tolerance: float = 0.01) -> np.ndarray:
    """Group readings that repeat one load state: consecutive in time within a configuration, at the same
    joints, with a force within ``tolerance`` of the campaign's largest force *of the group's first
    reading* (so a slow ramp of small steps never chains into one group). Returns a group id per reading.

    The points of a part (`stiffness.part.rows`) each sit at joints of their own: none repeats another."""
    f = ctx.wrench_sensor[:, :3]
    q = ctx.q
    tol = tolerance * max(np.linalg.norm(f, axis=1).max(), 1e-9)
    order = np.lexsort((ctx.time, ctx.config))
    gid = np.empty(ctx.n_readings, dtype=int)
    g, first = -1, None
    for n in order:
        if (first is None or ctx.config[first] != ctx.config[n] or np.linalg.norm(f[n] - f[first]) > tol
                or np.abs(q[n] - q[first]).max() > 1e-9):
            g += 1
            first = n
        gid[n] = g
    return gid


def pure_error(ctx: Context, y: np.ndarray) -> dict | None:
    """The measurement noise seen between repeated readings of one load state (model-free).

    ``y`` (N, 6) is NaN where a component was not measured (or a row is left out); each component
    counts its own measured repeats. A kind (position, rotation) not measured at all is NaN.

    Returns ``{"position_mm", "rotation_deg", "dof"}`` per component, or None when the repeats give
    fewer than MIN_PURE_ERROR_DOF degrees of freedom (the estimate would be looser than about 5 %)
    or show no scatter at all (noise-free data: there is no measured noise to judge against).
    """
    gid = repeat_groups(ctx)[ctx.row_reading]
    key = gid * len(BODIES) + ctx.body
    _, inv = np.unique(key, return_inverse=True)
    inv = inv.reshape(-1)
    ok = np.isfinite(y)
    counts = np.zeros((inv.max() + 1, 6))
    sums = np.zeros((inv.max() + 1, 6))
    np.add.at(counts, inv, ok)
    np.add.at(sums, inv, np.where(ok, y, 0.0))
    dof_c = np.sum(np.clip(counts - 1, 0, None), axis=0)           # per component
    dof = int(dof_c.max(initial=0))
    if dof < MIN_PURE_ERROR_DOF:
        return None
    dev = np.where(ok, y - (sums / np.maximum(counts, 1))[inv], 0.0)
    out = {}
    for kind, sl, floor in (("position_mm", slice(0, 3), MIN_NOISE_MM), ("rotation_deg", slice(3, 6), MIN_NOISE_DEG)):
        d = dof_c[sl].sum()
        ss = float(np.sum(dev[:, sl] ** 2)) / d if d else float("nan")
        if ss < floor**2:
            return None
        out[kind] = float(np.sqrt(ss))
    return {**out, "dof": dof}


def axial_residual(ctx: Context, resid: np.ndarray, sigma: np.ndarray, joint: int) -> np.ndarray:
    """Per reading, the axial rotation of ``joint`` (rad) that best explains its residual.

    The least-squares projection of the reading's residual (all its measured bodies, weighted by
    the noise) onto the deflection one unit of the joint's axial twist would cause; NaN where the
    reading holds no body that the joint moves.
    """
    r = resid / sigma
    g = np.where(np.isfinite(r), ctx.G[:, joint - 1, :, 5] / sigma, 0.0)   # (N, 6) per rad
    r = np.nan_to_num(r)
    num = np.bincount(ctx.row_reading, np.sum(g * r, axis=1), ctx.n_readings)
    den = np.bincount(ctx.row_reading, np.sum(g * g, axis=1), ctx.n_readings)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(den > 1e-12 * den.max(initial=0), num / den, np.nan)


def patterns(ctx: Context, resid: np.ndarray, sigma: np.ndarray) -> list[dict]:
    """How much of the residual simple regressors explain (R^2 each), strongest first.

    The probes are physical, not effects: time within a configuration, each joint torque's sign and
    square, and the sensor force along each axis. They point a person at a pattern
    when no library effect explains it.
    """
    rw = np.nan_to_num(resid / sigma)
    total = float(np.sum(rw**2))
    if total <= 0:
        return []
    W = ctx.frame_wrench
    probes = {"time within configuration": ctx.t_rel}
    for j in range(1, 7):
        tau = W[:, j - 1, 5]
        probes[f"sign of joint {j} torque"] = np.sign(tau)
        probes[f"joint {j} torque squared"] = tau**2
    for k, a in enumerate("xyz"):
        probes[f"sensor force f{a}"] = ctx.wrench_sensor[:, k]
    out = []
    rr = ctx.row_reading
    for name, x in probes.items():
        x = x[rr]
        # a separate slope per body and component: the probe may act on any of them
        explained = 0.0
        for b in np.unique(ctx.body):
            m = ctx.body == b
            xm = x[m] - x[m].mean()
            den = float(xm @ xm)
            if den > 0:
                explained += float(np.sum((xm @ (rw[m] - rw[m].mean(axis=0))) ** 2) / den)
        out.append({"pattern": name, "r2": explained / total})
    return sorted(out, key=lambda d: -d["r2"])
