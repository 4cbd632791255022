"""The static torque identified from the data: where each configuration crosses a joint's nonlinearity.

A gearbox's play or soft zone sits at zero *total* torque tau_s(q) + tau_ext (`stiffness.statics`). When
the robot's masses are approximate or missing, tau_s is wrong, and the fit identifies it:

    tau_s_j(q) = prior_j(q) + sum_k phi_jk(q) beta_k,

prior_j   the static torque of the robot's masses, balancer and payload (zero without masses);
phi_jk    column k of row j of the arm's static regressor: tau_arm = -Y(q) pi, Y pinocchio's joint torque
          regressor at rest (`computeJointTorqueRegressor` with v = a = 0), pi the links' masses and
          first moments (m, m c_x, m c_y, m c_z of link i in joint i's frame: DH frame i-1 turned with
          the joint); only the columns that row j can tell apart are kept (the base columns, QR with
          pivoting over random configurations);
beta_k    the correction of those base parameters *as joint j feels them*: a balancer's share on joint j
          scales its whole row, so it folds into beta (one joint's crossings cannot separate it from the
          masses).

The model holds one `PreloadTerm` per joint (YAML: the model's ``preload`` list, keys such as
``mx3_kgm``), identified by `identify.fit` as nonlinear parameters; `StiffnessModel.statics` adds it to
tau_s, so the offline prediction and the 1 ms service use it unchanged. A campaign sees tau_s only at
its configurations, and only where the external load crosses the nonlinearity: the directions of beta
the data cannot see stay at their start (named by the fit), and a configuration whose crossing lies
beyond its load range bounds tau_s there without fixing it (`crossings`).

Example: joint 2 of the KR 125 sees a few base columns of the 24 (m, mc of six links).

>>> from stiffness.robot import load_robot
>>> from stiffcomp_testlib import ROOT
>>> robot = load_robot(ROOT / "config" / "robots" / "kr125.yaml")
>>> t = PreloadTerm(robot, 2)
>>> len(t.params) < 24 and all(p.key.endswith(("_kg", "_kgm")) for p in t.params)
True
"""

from __future__ import annotations

from functools import lru_cache
from typing import Any

import numpy as np
from scipy.linalg import qr

from .effects.base import Effect, Param, read_location, read_values

PARTS = ("m", "mx", "my", "mz")          # pinocchio's dynamic parameters 0..3 of each link
N_COLUMNS = 6 * len(PARTS)
BEYOND = 1.3                             # a start puts an unseen crossing this far beyond the load range
RIDGE = 1e-3                             # the start's pull toward the prior, relative to the data


def static_regressor(pm, pd, q: np.ndarray) -> np.ndarray:
    """(6, 24): the arm's static torque (signed like the external joint torque) per unit of each link's
    m, m c_x, m c_y, m c_z, at configuration ``q`` (rad), for the gravity of ``pm``."""
    import pinocchio as pin

    zero = np.zeros(pm.nv)
    Y = pin.computeJointTorqueRegressor(pm, pd, np.asarray(q, dtype=float), zero, zero)
    return -Y.reshape(6, 6, 10)[:, :, :4].reshape(6, N_COLUMNS)


def column_key(k: int) -> str:
    link, part = divmod(k, len(PARTS))
    return f"{PARTS[part]}{link + 1}_{'kg' if part == 0 else 'kgm'}"


@lru_cache(maxsize=32)
def _base_columns(robot_id: int, joint: int, pm) -> tuple[int, ...]:
    rng = np.random.default_rng(0)
    lo = np.asarray(pm.lowerPositionLimit)
    hi = np.asarray(pm.upperPositionLimit)
    pd = pm.createData()
    Y = np.array([static_regressor(pm, pd, rng.uniform(lo, hi))[joint - 1] for _ in range(120)])
    _, R, piv = qr(Y, pivoting=True, mode="economic")
    d = np.abs(np.diag(R))
    rank = int(np.sum(d > 1e-6))                 # Nm per kg or kg m: a vertical joint 1 sees none
    return tuple(sorted(int(k) for k in piv[:rank]))


def base_columns(robot, joint: int) -> tuple[int, ...]:
    """The columns of the static regressor's row ``joint`` that the configurations tell apart."""
    return _base_columns(id(robot.pin_model), joint, robot.pin_model)


class PreloadTerm(Effect):
    """The identified correction of joint ``joint``'s static torque (module docstring). It adds no twist:
    it moves where the joint's axial nonlinearity sits (`Context.static_torque`)."""

    name = "preload"
    kind = "static"
    equation = "tau_s,j(q) = prior_j(q) + phi_j(q) beta"

    def __init__(self, robot: Any, joint: int, theta: np.ndarray | None = None):
        self.columns = np.array(base_columns(robot, joint), dtype=int)
        params = [Param(column_key(k), "kg" if k % 4 == 0 else "kg m", 10.0, nonlinear=True)
                  for k in self.columns]
        super().__init__(params, np.zeros(len(params)) if theta is None else theta, joint)

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> PreloadTerm:
        joint = read_location(section, "joint", cls.joints, where)
        probe = cls(robot, joint)
        return cls(robot, joint, read_values(cls.name, section, probe.params, where, ("joint",)))

    def to_config(self) -> dict[str, Any]:
        out = super().to_config()
        del out["effect"]
        return out

    def realtime(self, robot: Any) -> list:
        return []            # the service takes it through `StiffnessModel.statics`

    def phi(self, ctx) -> np.ndarray:
        """(R, K): the base columns at each reading of ``ctx``."""
        key = ("preload_phi", self.joint, tuple(self.columns))
        if key not in ctx.cache:
            from .statics import Statics

            statics = ctx.statics if ctx.statics is not None else Statics(ctx.robot)   # a robot without masses
            ctx.cache[key] = statics.regressor_rows(ctx.q, self.joint)[:, self.columns]
        return ctx.cache[key]

    def correction(self, ctx, theta: np.ndarray) -> np.ndarray:
        """(R,) Nm: what this term adds to joint j's static torque at each reading."""
        return self.phi(ctx) @ theta

    def size_text(self, estimate, std_error, model) -> str:
        return ", ".join(f"{p.key} {v:+.3g} (± {s:.2g})" for p, v, s in zip(self.params, estimate, std_error))


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
        parts.append("crossed at external " + _and(inside))
    if beyond:
        parts.append("preloaded beyond the load range in " + _and(beyond)
                     + " (these tell only a bound on the static torque)")
    return "; ".join(parts)


def _and(items: list[str]) -> str:
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " and " + items[-1]


def start_from_centres(model, ctx, term: PreloadTerm, tau_s_per_config: np.ndarray,
                       determined: np.ndarray) -> np.ndarray:
    """beta that puts joint j's static torque at ``tau_s_per_config`` in the ``determined``
    configurations and beyond the load range (by BEYOND) in the others, on the side a first fit to the
    determined ones gives: ridge regression toward the prior (beta = 0), in closed form."""
    C = len(ctx.config_labels)
    prior = np.full(C, np.nan)
    prior[ctx.config] = ctx.static_prior[:, term.joint - 1]
    phi = np.full((C, len(term.columns)), np.nan)
    phi[ctx.config] = term.phi(ctx)
    ok = determined & np.isfinite(tau_s_per_config)
    if not ok.any():
        return np.zeros(len(term.columns))
    beta = _ridge(phi[ok], tau_s_per_config[ok] - prior[ok])
    tau = np.abs(ctx.frame_wrench[:, term.joint - 1, 5])
    reach = np.zeros(C)
    np.maximum.at(reach, ctx.config, tau)
    guess = prior + phi @ beta
    target = np.where(ok, tau_s_per_config, np.where(guess >= 0, 1.0, -1.0) * np.maximum(np.abs(guess),
                                                                                            BEYOND * reach))
    seen = np.isfinite(target) & np.isfinite(prior)
    return _ridge(phi[seen], target[seen] - prior[seen])


def _ridge(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    norms = np.linalg.norm(A, axis=0)
    norms[norms <= 0] = 1.0
    An = A / norms
    lam = RIDGE * max(float(np.linalg.norm(An, 2)) ** 2, 1e-300)
    return np.linalg.solve(An.T @ An + lam * np.eye(An.shape[1]), An.T @ b) / norms


FAR_NM = 1e12           # a static torque beyond every load: the nonlinearity is not crossed there
EDGE = 0.05             # a crossing this close to the end of the load range is only a bound
STEP_NM = 10.0          # the fit's unit of change of an identified static torque (a backlash's width is tens of Nm)
GRID = 48               # trial crossings per configuration
MIN_GAIN = 100.0         # a crossing counts when it removes this many noise variances of the axial residual (repeats are correlated)


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
    from .residuals import axial_residual

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
    all trials of a grid at once (the step's columns projected off ``base``)."""
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
        k = int(np.argmin(rss))
        if rss[k] < best[0]:
            best = (float(rss[k]), float(grid[k]), float(b[k]))
    return best


def _rss(A: np.ndarray, y: np.ndarray) -> float:
    coef = np.linalg.lstsq(A, y, rcond=None)[0]
    return float(np.sum((y - A @ coef) ** 2))


def directions(model, ctx, nl: np.ndarray, scale: np.ndarray) -> np.ndarray | None:
    """(len(nl), Z), or None for a model without an identified preload: the directions the fit moves the nonlinear parameters ``nl`` in (scaled units).

    Every parameter moves alone, except an identified preload's: the campaign sees joint j's static
    torque only at its configurations, so its beta moves only in the row space of the base columns at
    those configurations; the rest of beta stays at its start (the prior)."""
    if not any(isinstance(e, PreloadTerm) for e in model.effects):
        return None
    labels = {}
    for e, sl in zip(model.effects, model.param_slices()):
        for k in range(sl.start, sl.stop):
            labels[k] = (e, sl)
    cols = []
    done = set()
    for i, k in enumerate(nl):
        e, sl = labels[int(k)]
        if not isinstance(e, PreloadTerm):
            col = np.zeros(len(nl))
            col[i] = 1.0
            cols.append(col)
            continue
        if id(e) in done:
            continue
        done.add(id(e))
        first = np.unique(ctx.config, return_index=True)[1]
        phi = e.phi(ctx)[first] * scale[sl]
        _, S, Vt = np.linalg.svd(phi, full_matrices=False)
        r = int(np.sum(S > 1e-6 * max(S[0], 1e-300))) if len(S) else 0
        pos = [i2 for i2, k2 in enumerate(nl) if sl.start <= k2 < sl.stop]
        for v, sv in zip(Vt[:r], S[:r]):         # one unit moves the configurations' tau_s by STEP_NM
            col = np.zeros(len(nl))
            col[pos] = v * STEP_NM / sv
            cols.append(col)
    return np.array(cols).T.reshape(len(nl), len(cols))


def held_preload(model) -> np.ndarray:
    """Boolean (P,): the model's parameters that belong to an identified preload."""
    return np.concatenate([np.full(len(e.params), isinstance(e, PreloadTerm)) for e in model.effects]) \
        if model.effects else np.zeros(0, dtype=bool)


def fresh_start(model, ctx, fit) -> None:
    """Start each identified preload still at its prior (beta = 0) where the data cross its joint's axial
    nonlinearity: `fit` the model without its axial effects and preloads, search the residual's steps per
    configuration (`centre_search`, the effect's own shape) and regress them (`start_from_centres`). In place."""
    from .effects.axial import AxialEffect

    fresh = [e for e in model.effects if isinstance(e, PreloadTerm) and not np.any(e.theta)]
    axial = {e.joint: e for e in model.effects if isinstance(e, AxialEffect)}
    fresh = [e for e in fresh if e.joint in axial]
    if not fresh:
        return
    from .model import StiffnessModel

    plain = [e for e in model.effects if not isinstance(e, (PreloadTerm, AxialEffect))]
    if not plain:
        return
    base = StiffnessModel(model.robot, plain, noise=model.noise, source=model.source, payload=model.payload)
    result = fit(base, ctx, rounds=1, robust=False)
    model.bind_preload(ctx)
    for term in fresh:
        e = axial[term.joint]
        theta = e.theta.copy()
        if theta[0] == 0:
            theta[0] = 1.0                 # the shape, not the size, is searched
        tau_s, found = centre_search(ctx, result.residual, result.sigma, term.joint, lambda t: e.shape(t, theta))
        term.theta = start_from_centres(model, ctx, term, tau_s, found)


def notes(model, ctx) -> list[str]:
    """Per identified preload, in words: where each configuration crosses (or only bounds) the static
    torque, and how many combinations of its base parameters the data leave at their prior."""
    from .effects.axial import AxialEffect

    out = []
    for term in (e for e in model.effects if isinstance(e, PreloadTerm)):
        model.bind_preload(ctx)
        first = np.unique(ctx.config, return_index=True)[1]
        seen = int(np.linalg.matrix_rank(term.phi(ctx)[first], tol=1e-6)) if len(term.columns) else 0
        has_axial = any(isinstance(e, AxialEffect) and e.joint == term.joint for e in model.effects)
        where = crossing_text(ctx, term.joint, centres(model, ctx, term.joint)) if has_axial else \
            "no axial nonlinearity at this joint to locate it"
        out.append(f"static torque of joint {term.joint} identified: {where}; the configurations see {seen} of its "
                   f"{len(term.columns)} base parameters, the other {len(term.columns) - seen} combination(s) "
                   "stay at the prior (the robot's masses, or zero without them)")
    return out
