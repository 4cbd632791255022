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
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.linalg import LinAlgError, cho_factor, cho_solve
from scipy.optimize import least_squares

from .context import Context
from .measurements import Dataset
from .model import StiffnessModel

T_DETERMINED = 3.0  # |estimate| / standard error below this: the data cannot tell it from zero


@dataclass
class FitResult:
    """The outcome of a fit. ``converged`` is False when the optimiser stopped without converging."""

    model: StiffnessModel
    residual: np.ndarray                   # (N, 6) measured - predicted, mm / deg
    sigma: np.ndarray                      # (6,) noise used as weights
    std_error: np.ndarray                  # (P,) SI
    t_value: np.ndarray                    # (P,)
    undetermined: list[str]
    converged: bool = True
    message: str = ""
    warnings: list[str] = field(default_factory=list)

    @property
    def rms_position_mm(self) -> float:
        return rms(self.residual[:, :3])

    @property
    def rms_rotation_deg(self) -> float:
        return rms(self.residual[:, 3:])


def rms(x: np.ndarray) -> float:
    """Root mean square over all entries (per component, not of the 3-D norm)."""
    return float(np.sqrt(np.mean(np.square(x)))) if np.size(x) else float("nan")


def solve_ls(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """min |A x - b| via normal equations on unit-norm columns (fast for tall A); lstsq if singular."""
    norms = np.linalg.norm(A, axis=0)
    norms[norms == 0] = 1.0
    An = A / norms
    M = An.T @ An
    try:
        if np.linalg.cond(M) > 1e12:
            raise LinAlgError
        x = cho_solve(cho_factor(M), An.T @ b)
    except LinAlgError:
        x = np.linalg.lstsq(An, b, rcond=None)[0]
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
        sigma: np.ndarray | None = None) -> FitResult:
    """Identify every parameter of ``model`` from ``data``; returns a fitted copy in the result.

    Parameters
    ----------
    rounds : int
        Fits, with the noise re-estimated from the residuals after each (the weights of the next
        round and of the standard errors).
    max_nfev : int
        Evaluations allowed to the nonlinear solver (only used when the model has nonlinear terms).
    sigma : (6,) array, optional
        Starting noise per component; defaults to the model's ``noise`` section.
    """
    model = model.copy()
    ctx = data if isinstance(data, Context) else model.context(data)
    y = ctx.data.deflection
    if sigma is None:
        sigma = np.array([model.noise["position_mm"]] * 3 + [model.noise["rotation_deg"]] * 3)
    scale = np.array([p.scale for e in model.effects for p in e.params])
    lin = linear_index(model)
    nl = np.setdiff1d(np.arange(len(scale)), lin)
    converged, message = True, "closed-form least squares"
    theta = model.theta.copy()
    for _ in range(max(1, rounds)):
        if len(nl):
            theta, converged, message = _solve_projected(model, ctx, y, sigma, scale, theta, lin, nl, max_nfev)
        else:
            theta = _solve_linear(model, ctx, y, sigma, theta, lin)
        theta = _exact_step(model, ctx, y, sigma, scale, theta)
        resid = y - model.predict(ctx, theta)
        sigma = _noise_from_residual(resid, sigma)
    model.theta = theta
    se, t = _standard_errors(jacobian(model, ctx, theta), resid, sigma, scale, theta)
    undetermined = [lab for lab, tv in zip(model.param_labels(), t) if not tv >= T_DETERMINED]
    for e, sl in zip(model.effects, model.param_slices()):
        e.std_error = se[sl]
    warnings = []
    if undetermined:
        warnings.append(f"{len(undetermined)} parameter(s) cannot be told from zero by these data "
                        f"(|estimate| < {T_DETERMINED:g} standard errors): " + ", ".join(undetermined))
    return FitResult(model, resid, sigma, se, t, undetermined, converged, str(message), warnings)


def _weighted(X: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    return (X / sigma[None, :, None]).reshape(-1, X.shape[2])


def _solve_linear(model, ctx, y, sigma, theta, lin):
    """The linear parameters in closed form, the others held at ``theta``."""
    theta = theta.copy()
    theta[lin] = 0.0
    rest = y - model.predict(ctx, theta, linear=True) if len(lin) < len(theta) else y
    X = design(model, ctx, model.frame_wrenches(ctx, theta), theta)
    theta[lin] = solve_ls(_weighted(X, sigma), (rest / sigma).reshape(-1))
    return theta


def _solve_projected(model, ctx, y, sigma, scale, theta, lin, nl, max_nfev):
    """least_squares over the nonlinear parameters; the linear ones solved inside each evaluation."""
    lo = np.array([_param(model, k).bounds[0] for k in nl]) / scale[nl]
    hi = np.array([_param(model, k).bounds[1] for k in nl]) / scale[nl]
    cache = {}

    def inner(x):
        th = theta.copy()
        th[nl] = x * scale[nl]
        th = _solve_linear(model, ctx, y, sigma, th, lin)
        cache["theta"] = th
        return ((y - model.predict(ctx, th, linear=True)) / sigma).reshape(-1)

    x0 = np.clip(theta[nl] / scale[nl], lo, hi)
    sol = least_squares(inner, x0, bounds=(lo, hi), x_scale=1.0, diff_step=1e-4, max_nfev=max_nfev,
                        method="trf")
    inner(sol.x)
    return cache["theta"], bool(sol.status > 0), sol.message


def _exact_step(model, ctx, y, sigma, scale, theta):
    """One Gauss-Newton step on the exact chain from the linearised optimum."""
    lo = np.array([p.bounds[0] for e in model.effects for p in e.params])
    hi = np.array([p.bounds[1] for e in model.effects for p in e.params])
    J = _weighted(jacobian(model, ctx, theta), sigma) * scale
    r = ((y - model.predict(ctx, theta)) / sigma).reshape(-1)
    return np.clip(theta + solve_ls(J, r) * scale, lo, hi)


def _noise_from_residual(resid: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    sp, sr = rms(resid[:, :3]), rms(resid[:, 3:])
    out = np.array([sp] * 3 + [sr] * 3)
    return np.where(out > 0, out, sigma)


def _standard_errors(X, resid, sigma, scale, theta):
    Xw = _weighted(X, sigma) * scale
    n, p = Xw.shape
    s2 = float(np.sum((resid / sigma) ** 2)) / max(n - p, 1)
    cov = np.linalg.pinv(Xw.T @ Xw) * s2
    se = np.sqrt(np.clip(np.diag(cov), 0, None)) * scale
    null = np.linalg.norm(Xw, axis=0) < 1e-12 * max(np.linalg.norm(Xw), 1e-300)
    se[null] = np.inf
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.abs(theta) / se
    return se, np.nan_to_num(t, nan=0.0)
