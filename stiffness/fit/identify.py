"""Identification: least squares of the model's parameters from measured deflections and wrenches.

Most parameters enter the deflection linearly (compliances, lost motion, offsets, rates). They are
solved in closed form: the joint-level form of Eq. 15, the residual of every measured body's six
components weighted by the noise of its kind (position in mm, rotation in deg). A Gauss-Newton step
on the exact (composed) chain follows, so composing finite rotations does not bias the estimate.

The few nonlinear parameters (a backlash's width, a knee torque, a sensor misalignment) are found by
scipy.optimize.least_squares over those parameters alone, with the linear ones solved inside each
evaluation (variable projection).

The noise of each kind is re-estimated from the residuals between rounds, so position and rotation
count by what the data show.

A prior (`stiffness.model.prior.Prior`: what a campaign already told of the parameters) adds rows that hold
the parameters near it, whitened like the data's; every step below solves the data's rows and the
prior's together, so new data (a machined part's points, `stiffness.part.learn`) move only what they
determine better than the prior did. The fit's own covariance is stored in the fitted model (the
YAML's ``covariance``), the prior of the next fit.

Only the measured components count (a laser tracker gives the TCP position alone): an unmeasured
entry has weight zero, and the parameters the measured components cannot determine at all are named
(`identifiability`) and kept at their starting values. By default the fit is robust: rows judged
gross errors (`gross_errors`) get weight zero in the next round and are reported by line.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve
from scipy.optimize import least_squares, lsq_linear

from ..data.campaign import Context
from ..data.measurements import Dataset
from ..data.residuals import repeat_groups
from ..kinematics.robot import BODIES
from ..model.preload_term import directions, held_preload
from ..model.prior import Prior, PriorRows, covariance_entry
from ..model.stiffness_model import StiffnessModel
from .gross_errors import gross_errors, robust_scale
from .identifiability import IDENT_TOL, unidentifiable_information
from .preload_fit import evidence, fresh_start
from .preload_fit import notes as preload_notes
from .result import FitResult, rms, weights
from .sanity import noise_warning

T_DETERMINED = 3.0  # |estimate| / standard error below this: the data cannot tell it from zero
ROBUST_EXTRA_ROUNDS = 3   # rounds a robust fit may add while its set of gross errors still changes


def solve_ls(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """min |A x - b| via normal equations on unit-norm columns (fast for tall A).

    When the columns are (nearly) dependent (singular value ratio below IDENT_TOL), the minimum-norm
    solution in the scaled parameters: the directions the data cannot see get no step.
    """
    norms = np.linalg.norm(A, axis=0)
    dead = norms <= 1e-12 * max(float(norms.max(initial=0.0)), 1e-300)   # rounding, not a signal
    norms[dead] = 1.0
    An = np.where(dead, 0.0, A / norms)
    M = An.T @ An
    try:
        if np.linalg.cond(M) > IDENT_TOL**-2:
            raise LinAlgError
        x = cho_solve(cho_factor(M), An.T @ b)
    except LinAlgError:
        x = np.linalg.lstsq(An, b, rcond=IDENT_TOL)[0]
    return x / norms


def linear_index(model: StiffnessModel) -> np.ndarray:
    """Indices (into model.theta) of the parameters that enter linearly, in design-column order."""
    idx = []
    for e, sl in zip(model.effects, model.param_slices()):
        if e.kind == "site":
            idx.extend(np.arange(sl.start, sl.stop)[e.linear_mask])
    return np.array(idx, dtype=int)


def design(model: StiffnessModel, ctx: Context, W: np.ndarray, theta: np.ndarray,
           effects=None) -> np.ndarray:
    """Design matrix (N, 6, P_linear): d(deflection)/d(linear parameter), mm or deg per SI unit."""
    cols = []
    rr = ctx.row_reading
    model.bind_preload(ctx, theta)
    for e, sl in zip(model.effects, model.param_slices()):
        if e.kind != "site" or (effects is not None and e not in effects):
            continue
        B = e.basis(ctx, W, theta[sl])                                   # (R, P, 12, 6)
        sites = np.nonzero(np.any(B != 0, axis=(0, 1, 3)))[0]
        if len(sites) == 0:
            cols.append(np.zeros((len(rr), 6, B.shape[1])))
            continue
        cols.append(np.einsum("nsab,npsb->nap", ctx.G[:, sites], B[rr][:, :, sites]))
    return np.concatenate(cols, axis=2) if cols else np.zeros((len(rr), 6, 0))


def jacobian(model: StiffnessModel, ctx: Context, theta: np.ndarray | None = None) -> np.ndarray:
    """d(deflection)/d(theta) (N, 6, P), mm or deg per SI unit, on the linearised chain.

    Linear parameters give their columns in closed form; nonlinear ones are differentiated by central
    differences with a step of 1e-3 of the parameter's scale.
    """
    theta = model.theta if theta is None else np.asarray(theta, dtype=float)
    J = np.zeros((len(ctx.body), 6, len(theta)))
    lin = linear_index(model)
    J[:, :, lin] = design(model, ctx, model.frame_wrenches(ctx, theta), theta)
    for k in np.setdiff1d(np.arange(len(theta)), lin):
        p = _param(model, k)
        h = 1e-3 * p.scale
        up, dn = theta.copy(), theta.copy()
        up[k] = min(theta[k] + h, p.bounds[1])
        dn[k] = max(theta[k] - h, p.bounds[0])
        J[:, :, k] = (model.predict(ctx, up, linear=True) - model.predict(ctx, dn, linear=True)) / (up[k] - dn[k])
    return J


def _param(model, k):
    return [p for e in model.effects for p in e.params][k]


def fit(model: StiffnessModel, data: Dataset | Context, rounds: int = 2, max_nfev: int = 100,
        sigma: np.ndarray | None = None, robust: bool = True, nonnegative: bool = False,
        progress: Callable[[str], None] | None = None, prior: Prior | None = None) -> FitResult:
    """Identify every parameter of ``model`` from ``data``; returns a fitted copy in the result.

    Parameters
    ----------
    rounds : int
        Fits, with the noise re-estimated from the residuals after each (the weights of the next
        round and of the standard errors).
    max_nfev : int
        Evaluations allowed to the nonlinear solver (only used when the model has nonlinear terms).
    sigma : (6,) array, optional
        Starting noise per component (mm, deg); defaults to the model's ``noise`` section.
    robust : bool
        Give rows judged gross errors (`gross_errors.gross_errors`) weight zero, re-judging after each
        round; up to ROBUST_EXTRA_ROUNDS more rounds while that set still changes. False: plain
        weighted least squares over every row.
    nonnegative : bool
        Bound every compliance (`Param.compliance`) at >= 0: bounded linear least squares
        (scipy.optimize.lsq_linear). The result's warnings name the compliances held at the bound.
        Unbounded (default), a negative compliance is kept and named in a warning.
    progress : callable, optional
        Called with a few words at each stage and at each evaluation of the nonlinear solver (a fit with
        an identified preload takes minutes); `tools.common.Progress` shows them.
    prior : Prior, optional
        What is known of the parameters before these data (`stiffness.model.prior`): its rows are solved with
        the data's at every step, and the standard errors and the covariance include it.
    """
    say = progress or (lambda stage: None)
    start = model.theta.copy()
    model = model.copy()
    pr = PriorRows(prior, model)
    ctx = data if isinstance(data, Context) else model.context(data)
    fresh_start(model, ctx, fit, say)      # an identified preload still at its prior: start where the data step
    measured = ctx.data.measured
    y = np.where(measured, ctx.data.deflection, 0.0)
    stated = np.array([model.noise["position_mm"]] * 3 + [model.noise["rotation_deg"]] * 3)
    sigma = stated if sigma is None else np.asarray(sigma, dtype=float)
    scale = np.array([p.scale for e in model.effects for p in e.params])
    lin = linear_index(model)
    compliance = np.array([p.compliance for e in model.effects for p in e.params], dtype=bool)
    lower = np.where(compliance & nonnegative, 0.0, -np.inf)
    theta, resid, sigma, inlier, converged, message = _rounds(model, ctx, y, sigma, stated, scale, lin, lower, pr,
                                                              rounds, max_nfev, robust, say)
    model.theta = theta
    w = weights(measured, inlier, sigma)
    J = jacobian(model, ctx, theta)
    Jw = _weighted(J, w) * scale
    blind = unidentifiable_information(Jw.T @ Jw + pr.information(scale))
    se, t, cov = _standard_errors(J, resid, w, scale, theta, blind, pr)
    model.covariance = covariance_entry(model, cov, _source_text(ctx, prior))
    labels = model.param_labels()
    own = held_preload(model)      # an identified preload's unseen combinations are named by its own lines
    undetermined = [lab for lab, tv, o in zip(labels, t, own) if not tv >= T_DETERMINED and not o]
    for e, sl in zip(model.effects, model.param_slices()):
        e.std_error = se[sl]
    unident = [lab for lab, b, o in zip(labels, blind, own) if b and not o]
    warnings = _warnings(model, ctx, unident, undetermined, compliance, nonnegative, start)
    say("checking each identified preload against the noise")
    found = evidence(model, ctx, y, w, resid, lambda m, th: _solve_linear(m, ctx, y, w, th, linear_index(m)))
    result = FitResult(model=model, residual=resid, sigma=sigma, std_error=se, t_value=t, undetermined=undetermined,
                       converged=converged, message=str(message), warnings=warnings, unidentifiable=unident,
                       outlier=~inlier, lines=ctx.data.line, preload=preload_notes(model, ctx, found),
                       preload_evidence=found, covariance=cov)
    if result.outlier.any():
        warnings.append(f"{int(result.outlier.sum())} row(s) judged gross errors and left out, at line(s) "
                        + ", ".join(map(str, result.outlier_lines[:20]))
                        + (" ..." if result.outlier.sum() > 20 else ""))
    return result


def _rounds(model, ctx, y, sigma, stated, scale, lin, lower, pr, rounds, max_nfev, robust, say):
    """The fit's rounds: solve (closed form, or variable projection over the nonlinear parameters), take the
    exact Gauss-Newton step, judge the gross errors, re-estimate the noise. Returns theta, the residual, the
    noise, the rows used, whether the solver converged and its message."""
    measured = ctx.data.measured
    nl = np.setdiff1d(np.arange(len(scale)), lin)
    converged, message = True, "closed-form least squares"
    theta = model.theta.copy()
    inlier = np.ones(len(y), dtype=bool)
    group = _repeat_key(ctx) if robust else None
    n_rounds, k = max(1, rounds), 0
    while k < n_rounds:
        w = weights(measured, inlier, sigma)
        stage = f"round {k + 1} of {n_rounds}"
        say(stage)
        if len(nl):
            def counted(n: int, stage: str = stage) -> None:
                say(f"{stage}: {n} evaluations of the {len(nl)} nonlinear parameters")
            theta, converged, message = _solve_projected(model, ctx, y, w, scale, theta, lin, nl, max_nfev,
                                                         lower, counted, pr)
        else:
            theta = _solve_linear(model, ctx, y, w, theta, lin, lower, pr)
        theta = _exact_step(model, ctx, y, w, scale, theta, lower, pr)
        resid = np.where(measured, y - model.predict(ctx, theta), np.nan)
        if robust:
            keep = ~gross_errors(resid, robust_scale(resid, stated), group)
            if k == n_rounds - 1 and np.any(keep != inlier) and n_rounds < rounds + ROBUST_EXTRA_ROUNDS:
                n_rounds += 1          # the set changed: fit once more without the rows now judged
            if k < n_rounds - 1:
                inlier = keep
        sigma = _noise_from_residual(resid[inlier], sigma)
        k += 1
    return theta, resid, sigma, inlier, converged, message


def _warnings(model, ctx, unident, undetermined, compliance, nonnegative, start) -> list[str]:
    """The fit's warnings: what the data cannot determine, compliances below zero, the noise's units."""
    warnings = []
    if unident:
        warnings.append(f"{len(unident)} parameter(s) cannot be determined by the measured components at all "
                        "(kept at their starting values): " + ", ".join(unident))
    if undetermined:
        warnings.append(f"{len(undetermined)} parameter(s) cannot be told from zero by these data "
                        f"(|estimate| < {T_DETERMINED:g} standard errors): " + ", ".join(undetermined))
    warnings += _compliance_warnings(model, compliance, nonnegative, start)
    measured = ctx.data.measured
    units = noise_warning(model, ctx, np.where(measured, ctx.data.deflection, np.nan))
    if units:
        warnings.append(units)
    return warnings


def _repeat_key(ctx: Context) -> np.ndarray:
    """A repeat-group id per row: the same body in the readings of one load state."""
    return repeat_groups(ctx)[ctx.row_reading] * len(BODIES) + ctx.body


def _weighted(X: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Rows of X (N, 6, P) times the residual weights w (N, 6), stacked to (6N, P)."""
    return (X * w[:, :, None]).reshape(-1, X.shape[2])


def _solve_linear(model, ctx, y, w, theta, lin, lower=None, prior=None):
    """The linear parameters in closed form (minimum-norm step from ``theta``), the others held.

    With ``lower`` (P,) below which a parameter may not go (-inf: unbounded), and any finite, the
    bounded problem is solved by scipy.optimize.lsq_linear on unit-norm columns instead. With ``prior``
    (`stiffness.model.prior.PriorRows`) its rows are solved with the data's."""
    theta = theta.copy()
    start = theta[lin].copy()
    theta[lin] = 0.0
    rest = y - model.predict(ctx, theta, linear=True) if len(lin) < len(theta) else y
    X = design(model, ctx, model.frame_wrenches(ctx, theta), theta)
    Xw = _weighted(X, w)
    b = (rest * w).reshape(-1)
    if prior is not None and prior.R.shape[0]:          # R theta_lin = c - R theta_other
        Xw = np.vstack([Xw, prior.R[:, lin]])
        b = np.concatenate([b, prior.c - prior.R @ theta])
    lo = None if lower is None else lower[lin]
    if lo is None or not np.isfinite(lo).any():
        theta[lin] = start + solve_ls(Xw, b - Xw @ start)
        return theta
    norms = np.linalg.norm(Xw, axis=0)
    norms[norms <= 0] = 1.0
    sol = lsq_linear(Xw / norms, b, bounds=(np.where(np.isfinite(lo), lo * norms, -np.inf), np.inf),
                     method="bvls")
    theta[lin] = sol.x / norms
    return theta


def _compliance_warnings(model: StiffnessModel, compliance: np.ndarray, nonnegative: bool, start) -> list[str]:
    """Name the negative compliances (unbounded fit) or those held at the bound of 0 (bounded fit): the data
    pushed them there, or the starting model (its values ``start``) already held them below zero."""
    labels = model.param_labels()
    if nonnegative:
        held = {False: [], True: []}
        for lab, c, v, s in zip(labels, compliance, model.theta, start):
            if c and v <= 0:
                held[bool(s < 0)].append(lab)
        why = {False: "because the data push them below zero", True: "because the starting model already held "
               "them below zero (not physical; the bound, not the data, set them to 0)"}
        return [f"the non-negative bound is active on {len(held[k])} compliance(s), held at 0 {why[k]}: "
                + ", ".join(held[k]) for k in (False, True) if held[k]]
    problem = model.unphysical()
    if not problem:
        return []
    return [(f"{problem}. The data may not determine them (see their standard errors), or the model misses "
            "an effect; `--nonnegative` bounds them at 0. The service refuses a model holding one")]


def _solve_projected(model, ctx, y, w, scale, theta, lin, nl, max_nfev, lower=None, counted=None, prior=None):
    """least_squares over the nonlinear parameters; the linear ones solved inside each evaluation (each
    counted with ``counted(n)``; with the prior's rows, `stiffness.model.prior.PriorRows`, in both)."""
    lo = np.array([_param(model, k).bounds[0] for k in nl]) / scale[nl]
    hi = np.array([_param(model, k).bounds[1] for k in nl]) / scale[nl]
    x0 = np.clip(theta[nl] / scale[nl], lo, hi)
    T = directions(model, ctx, nl, scale)      # an identified preload moves only where the data see it
    cache = {}

    def inner(z):
        cache["n"] = cache.get("n", 0) + 1
        if counted is not None:
            counted(cache["n"])
        th = theta.copy()
        th[nl] = (z if T is None else x0 + T @ z) * scale[nl]
        th = _solve_linear(model, ctx, y, w, th, lin, lower, prior)
        cache["theta"] = th
        r = ((y - model.predict(ctx, th, linear=True)) * w).reshape(-1)
        return r if prior is None else np.concatenate([r, prior.residual(th)])

    if T is None:
        z0, bounds = x0, (lo, hi)
    else:
        z0 = np.zeros(T.shape[1])
        one = np.sum(T != 0, axis=0) == 1            # a parameter moving alone keeps its bounds
        k = np.argmax(T != 0, axis=0)
        d = np.where(one, T[k, np.arange(len(k))], 1.0)
        bounds = (np.where(one, (lo[k] - x0[k]) / d, -np.inf), np.where(one, (hi[k] - x0[k]) / d, np.inf))
    sol = least_squares(inner, z0, bounds=bounds, x_scale=1.0, diff_step=1e-4, max_nfev=max_nfev, method="trf")
    inner(sol.x)
    return cache["theta"], bool(sol.status > 0), sol.message


def _exact_step(model, ctx, y, w, scale, theta, lower=None, prior=None):
    """One Gauss-Newton step on the exact chain from the linearised optimum (kept within the
    parameters' bounds and ``lower``). An identified preload is held: it moves a step function, which
    a linearisation does not follow (`stiffness.model.preload_term`)."""
    lo = np.array([p.bounds[0] for e in model.effects for p in e.params])
    if lower is not None:
        lo = np.maximum(lo, lower)
    hi = np.array([p.bounds[1] for e in model.effects for p in e.params])
    J = _weighted(jacobian(model, ctx, theta), w) * scale
    r = ((y - model.predict(ctx, theta)) * w).reshape(-1)
    if prior is not None and prior.R.shape[0]:
        J = np.vstack([J, prior.R * scale])
        r = np.concatenate([r, -prior.residual(theta)])
    J[:, held_preload(model)] = 0.0
    return np.clip(theta + solve_ls(J, r) * scale, lo, hi)


def _noise_from_residual(resid: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """Noise per component: the RMS of the measured residuals of its kind (position, rotation)."""
    out = np.array(sigma, dtype=float)
    for sl in (slice(0, 3), slice(3, 6)):
        s = rms(resid[:, sl])
        if s > 0:
            out[sl] = s
    return out


def _standard_errors(X, resid, w, scale, theta, blind, prior):
    """Standard errors (P,), t values (P,) and the covariance (P, P, SI; inf where not determined).

    The data's information is scaled by the residual's variance per degree of freedom, s2 (about 1 when
    the noise is right); the prior's counts as stated."""
    Xw = _weighted(X, w) * scale
    p = Xw.shape[1]
    n = int(np.count_nonzero(w))
    s2 = float(np.sum(np.nan_to_num(resid * w) ** 2)) / max(n - p, 1)
    cov = np.linalg.pinv(Xw.T @ Xw / max(s2, 1e-300) + prior.information(scale))
    cov = 0.5 * (cov + cov.T) * np.outer(scale, scale)    # pinv's rounding leaves it unequal across
    cov[blind, :] = 0.0
    cov[:, blind] = 0.0
    cov[blind, blind] = np.inf
    se = np.sqrt(np.clip(np.diag(cov), 0, None))
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.abs(theta) / se
    return se, np.nan_to_num(t, nan=0.0), cov


def _source_text(ctx: Context, prior: Prior | None) -> str:
    """What the fit's covariance summarises, in words (the model YAML's covariance.source)."""
    n, m = len(ctx.data), int(ctx.data.measured.any(axis=1).sum())     # a part's: its points, and the trace between
    rows = f"{n} rows" if m == n else f"{m} rows measured; {n - m} more carry only the load's history"
    data = f"{ctx.data.source} ({rows})"
    return data if prior is None else f"{data} with the prior {prior.source}"
