"""Identification: least squares of the model's parameters from measured deflections and wrenches.

Linear models (springs and every effect linear in its parameters) are solved in closed form, the
joint-level form of Eq. 15: the residual of every body's six components, weighted by the noise of
its kind (position in mm, rotation in deg), is minimised over the compliances. One Gauss-Newton
step on the exact loaded chain follows, so the small nonlinearity of composing rotations does not
bias the estimate. Models with nonlinear terms go through scipy.optimize.least_squares.

The noise per kind is re-estimated from the residuals (two rounds), so position and rotation count
by what the data show, not by a guess.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
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


def design(model: StiffnessModel, ctx: Context, W: np.ndarray, effects=None) -> np.ndarray:
    """Design matrix (N, 6, P) of the linear site effects: d(deflection)/d(theta), mm or deg per SI."""
    effects = model.effects if effects is None else effects
    cols = []
    rr = ctx.row_reading
    for e in effects:
        B = e.basis(ctx, W)                                           # (R, P, 12, 6)
        sites = np.nonzero(np.any(B != 0, axis=(0, 1, 3)))[0]
        if len(sites) == 0:
            cols.append(np.zeros((len(rr), 6, B.shape[1])))
            continue
        cols.append(np.einsum("nsab,npsb->nap", ctx.G[:, sites], B[rr][:, :, sites]))
    return np.concatenate(cols, axis=2) if cols else np.zeros((len(rr), 6, 0))


def fit(model: StiffnessModel, data: Dataset | Context, rounds: int = 2, max_nfev: int = 200,
        sigma: np.ndarray | None = None) -> FitResult:
    """Identify every parameter of ``model`` from ``data``; returns a fitted copy in the result.

    Parameters
    ----------
    rounds : int
        Fits with the noise re-estimated from the residuals in between (1 keeps ``sigma``).
    max_nfev : int
        Function evaluations allowed to the nonlinear solver.
    sigma : (6,) array, optional
        Starting noise per component; defaults to the model's ``noise`` section.
    """
    model = model.copy()
    ctx = data if isinstance(data, Context) else model.context(data)
    y = ctx.data.deflection
    if sigma is None:
        sigma = np.array([model.noise["position_mm"]] * 3 + [model.noise["rotation_deg"]] * 3)
    scale = np.array([p.scale for e in model.effects for p in e.params])
    linear = all(e.linear for e in model.effects)
    converged, message = True, "linear least squares"
    for _ in range(max(1, rounds)):
        if linear:
            theta, X = _solve_linear(model, ctx, y, sigma, scale)
        else:
            theta, X, converged, message = _solve_nonlinear(model, ctx, y, sigma, scale, max_nfev)
        model.theta = theta
        resid = y - model.predict(ctx)
        sigma = _noise_from_residual(resid, sigma)
    se, t = _standard_errors(X, resid, sigma, scale, theta)
    labels = model.param_labels()
    undetermined = [lab for lab, tv in zip(labels, t) if not tv >= T_DETERMINED]
    k = 0
    for e in model.effects:
        e.std_error = se[k:k + len(e.params)]
        k += len(e.params)
    warnings = []
    if undetermined:
        warnings.append(f"{len(undetermined)} parameter(s) cannot be told from zero by these data "
                        f"(|estimate| < {T_DETERMINED:g} standard errors): " + ", ".join(undetermined))
    return FitResult(model, resid, sigma, se, t, undetermined, converged, message, warnings)


def _weighted(X: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    return (X / sigma[None, :, None]).reshape(-1, X.shape[2])


def _solve_linear(model, ctx, y, sigma, scale):
    X = design(model, ctx, ctx.frame_wrench)
    Xw = _weighted(X, sigma) * scale
    yw = (y / sigma).reshape(-1)
    z = np.linalg.lstsq(Xw, yw, rcond=None)[0]
    theta = z * scale
    # Gauss-Newton correction on the exact (composed) chain.
    r = ((y - model.predict(ctx, theta)) / sigma).reshape(-1)
    theta = theta + np.linalg.lstsq(Xw, r, rcond=None)[0] * scale
    return theta, X


def _solve_nonlinear(model, ctx, y, sigma, scale, max_nfev):
    """least_squares over all parameters, started from the linear parameters' closed-form fit."""
    theta0 = model.theta.copy()
    lin_idx = np.concatenate([np.arange(sl.start, sl.stop) for e, sl in zip(model.effects, model.param_slices())
                              if e.linear] or [np.zeros(0, int)]).astype(int)
    if len(lin_idx):
        W = model.frame_wrenches(ctx, theta0)
        Xl = design(model, ctx, W, [e for e in model.effects if e.linear])
        rest = y - _predict_without(model, ctx, theta0, lin_idx)
        z = np.linalg.lstsq(_weighted(Xl, sigma) * scale[lin_idx], (rest / sigma).reshape(-1), rcond=None)[0]
        theta0[lin_idx] = z * scale[lin_idx]
    lo = np.array([p.bounds[0] for e in model.effects for p in e.params]) / scale
    hi = np.array([p.bounds[1] for e in model.effects for p in e.params]) / scale
    x0 = np.clip(theta0 / scale, lo + 1e-12, hi - 1e-12) if np.isfinite(lo).any() or np.isfinite(hi).any() \
        else theta0 / scale

    def fun(x):
        return ((y - model.predict(ctx, x * scale, linear=True)) / sigma).reshape(-1)

    sol = least_squares(fun, x0, bounds=(lo, hi), x_scale="jac", max_nfev=max_nfev, method="trf")
    theta = sol.x * scale
    X = -sol.jac.reshape(len(y), 6, -1) * sigma[None, :, None] / scale
    # polish on the exact chain
    r = ((y - model.predict(ctx, theta)) / sigma).reshape(-1)
    step = np.linalg.lstsq(_weighted(X, sigma) * scale, r, rcond=None)[0] * scale
    theta = np.clip(theta + step, lo * scale, hi * scale)
    return theta, X, bool(sol.success), sol.message


def _predict_without(model, ctx, theta, idx):
    th = theta.copy()
    th[idx] = 0.0
    return model.predict(ctx, th, linear=True)


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
