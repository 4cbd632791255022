"""Where a joint's axial nonlinearity is crossed, per configuration: the centre search on the residual, the
crossings in the external torque and their text (`stiffness.model.preload_term`, the diagnosis' free-centre variants).

A play or soft zone sits at zero total torque tau_s + tau_ext, so configuration c crosses it at the
external torque -tau_s(q_c); a configuration whose crossing lies beyond its load range bounds tau_s
there without fixing it.
"""

from __future__ import annotations

import numpy as np

from .residuals import axial_residual

FAR_NM = 1e12           # a static torque beyond every load: the nonlinearity is not crossed there
EDGE = 0.05             # a crossing this close to the end of the load range is only a bound
GRID = 48               # trial crossings per configuration
MIN_GAIN = 100.0         # a crossing counts when it removes this many noise variances of the axial residual (repeats are correlated)
TIE = 1e-12             # sums of squares this close (share of the data's) tie: only rounding tells them apart


def centres(model, ctx, joint: int) -> np.ndarray:
    """tau_s of ``joint`` per configuration (C,) Nm, as the model holds it (readings of a configuration share q)."""
    tau_s = ctx.static_torque[:, joint - 1]
    out = np.full(len(ctx.config_labels), np.nan)
    out[ctx.config] = tau_s
    return out


def crossings(ctx, joint: int, tau_s_per_config: np.ndarray, margin: float = 0.0) -> list[tuple[str, float, bool]]:
    """Per configuration (label, external torque where the total crosses zero = -tau_s, within its load range)."""
    tau = ctx.frame_wrench[:, joint - 1, 5]
    out = []
    for c, label in enumerate(ctx.config_labels):
        m = ctx.config == c
        if not m.any():
            continue
        lo, hi = float(tau[m].min()), float(tau[m].max())
        x = -float(tau_s_per_config[c])
        out.append((str(label), x, bool(np.isfinite(x) and lo - margin <= x <= hi + margin)))
    return out


def crossing_text(ctx, joint: int, tau_s_per_config: np.ndarray, margin: float = 0.0) -> str:
    """'crossed at external -310 Nm in C2 and -640 Nm in C4; preloaded beyond the load range in C6'."""
    cr = crossings(ctx, joint, tau_s_per_config, margin)
    inside = [f"{x:+.0f} Nm in {lab}" for lab, x, ok in cr if ok]
    beyond = [lab for lab, _, ok in cr if not ok]
    parts = []
    if inside:
        parts.append("crossed at external " + and_join(inside))
    if beyond:
        parts.append("preloaded beyond the load range in " + and_join(beyond)
                     + " (these tell only a bound on the static torque)")
    return "; ".join(parts)


def and_join(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def centre_search(ctx, resid: np.ndarray, sigma: np.ndarray, joint: int, shape) -> tuple[np.ndarray, np.ndarray]:
    """Per configuration, the static torque at which joint ``joint``'s axial residual steps.

    The unexplained axial rotation of each reading (`residuals.axial_residual`) is regressed, per
    configuration, on an offset, the external torque tau (the spring's misfit) and b (shape(T + tau) -
    shape(T)), for T over a grid that puts the crossing (external torque -T) inside the configuration's
    load range. First pass: b free per configuration; the configurations where a step removes at least
    MIN_GAIN noise variances give the common size b (their median). Second pass, b held: each
    configuration's best T, or no crossing at all when that fits as well (its preload lies beyond its
    load range, or the crossing lies within EDGE of its end). Returns (tau_s (C,) Nm, NaN where not
    found; found (C,) bool).
    """
    s = axial_residual(ctx, resid, sigma, joint)
    tau = ctx.frame_wrench[:, joint - 1, 5]
    C = len(ctx.config_labels)
    out, found = np.full(C, np.nan), np.zeros(C, dtype=bool)
    cfgs = []
    for c in range(C):
        m = (ctx.config == c) & np.isfinite(s)
        if m.sum() >= 8:
            cfgs.append((c, tau[m], s[m]))
    sizes = []
    for c, t, y in cfgs:
        rss0, base = _rss(np.column_stack([np.ones_like(t), t]), y), np.column_stack([np.ones_like(t), t])
        rss1, x, b = _best_crossing(t, y, base, shape, None)
        if b > 0 and rss0 - rss1 > MIN_GAIN * rss1 / max(len(y) - 4, 1):
            sizes.append(b)
    if len(sizes) < 2:
        return out, found
    size = float(np.median(sizes))
    for c, t, y in cfgs:
        base = np.column_stack([np.ones_like(t), t])
        rss0 = _rss(base, y)
        rss1, x, _ = _best_crossing(t, y, base, shape, size)
        lo, hi = float(t.min()), float(t.max())
        inside = lo + EDGE * (hi - lo) <= x <= hi - EDGE * (hi - lo)
        if inside and rss0 - rss1 > MIN_GAIN * rss1 / max(len(y) - 3, 1):
            out[c], found[c] = -x, True
    return out, found


def _best_crossing(t, y, base, shape, size):
    """(rss, crossing x, size) of the best step over a grid of crossings x in the range of t, refined.
    Each trial is the regression of y on ``base`` and the step (its size free, or held at ``size``),
    all trials of a grid at once (the step's columns projected off ``base``). Where the step's shape is
    flat at every load state, the trials between two of them fit alike to the last bits: their middle
    is taken (`_middle`), not whichever the rounding of this machine's BLAS made smallest."""
    lo, hi = float(t.min()), float(t.max())
    step = (hi - lo) / (GRID + 1)
    Q = np.linalg.qr(base)[0]
    ry = y - Q @ (Q.T @ y)
    best = (np.inf, np.nan, 0.0)
    for grid in (np.linspace(lo, hi, GRID + 2)[1:-1], None):
        if grid is None:                       # refine around the coarse best
            grid = best[1] + np.linspace(-step, step, 21)
        G = shape(t[:, None] - grid[None, :]) - shape(-grid)[None, :]
        RG = G - Q @ (Q.T @ G)
        gg = np.einsum("ij,ij->j", RG, RG)
        gy = RG.T @ ry
        if size is None:
            b = np.where(gg > 0, gy / np.where(gg > 0, gg, 1.0), 0.0)
            rss = ry @ ry - b * gy
        else:
            b = np.full(len(grid), size)
            rss = ry @ ry - 2 * size * gy + size**2 * gg
        k = _middle(rss, TIE * float(ry @ ry))
        best = (float(rss[k]), float(grid[k]), float(b[k]))     # the refined grid holds the coarse best
    return best


def _middle(rss: np.ndarray, tol: float) -> int:
    """The middle of the run of trials about the smallest ``rss`` that lie within ``tol`` of it (ties)."""
    k = int(np.argmin(rss))
    a, b = k, k
    while a > 0 and rss[a - 1] <= rss[k] + tol:
        a -= 1
    while b < len(rss) - 1 and rss[b + 1] <= rss[k] + tol:
        b += 1
    return (a + b) // 2


def _rss(A: np.ndarray, y: np.ndarray) -> float:
    coef = np.linalg.lstsq(A, y, rcond=None)[0]
    return float(np.sum((y - A @ coef) ** 2))
