"""Model discovery: fit the model, then try every library effect it lacks and name the one missing.

Method. The model is fitted and linearised at its optimum (Jacobian J0, weighted residual r0).
Each candidate (an effect at a joint or link, or a global one) adds columns Xc: the deflection
per unit of its parameters (a Gauss-Newton step from the optimum, exact for effects that enter
linearly; an effect's nonlinear shape, such as a backlash width or a knee torque, is tried over a
small grid and the best is kept). Each candidate is judged by three criteria:

* cross-validation grouped by configuration: the fraction of held-out squared error it removes,
  ``cv_improvement`` in [0, 1] (a criterion when >= CV_MIN);
* BIC: n ln(RSS1/RSS0) + k ln(n) below -BIC_MIN;
* an F-test of the nested models, p below ALPHA / (number of candidates).

It counts (``significant``) only if it passes cross-validation and at least one of the two
in-sample tests. When the residual still holds structure (a body's RMS above LACK_OF_FIT times the
noise seen between repeated readings), the named effect must also remove at least EXCESS_MIN of the
residual's excess over that noise; an effect that only nibbles at the structure is not named.
Without enough repeated readings the model's stated noise is the reference, with the looser
threshold LACK_OF_FIT_STATED. Cross-validation is required because, when the residual holds structure no
candidate describes, the in-sample tests on tens of thousands of correlated residuals pass for any
effect that soaks up part of it, while only an effect that predicts held-out configurations is
physical. Candidates are ranked by cv_improvement. The verdict is ``missing_effect`` when one counts; otherwise ``unexplained`` when
the residual is still above the noise seen between repeated readings, and ``no_missing_effect``
when it is not.
"""

from __future__ import annotations

import copy
from dataclasses import dataclass, field

import numpy as np
from scipy.stats import f as f_dist

from ..data.campaign import Context
from ..data.measurements import Dataset
from ..data.residuals import pure_error, worst
from ..effects import EFFECTS, Effect
from ..errors import DataError
from ..fit.identify import design, fit, jacobian
from ..fit.result import FitResult, rms
from ..model.preload_term import PreloadTerm, held_preload, start_from_centres
from ..model.prior import Prior
from ..model.stiffness_model import StiffnessModel
from .explain import describe, nanmax, verdict_of

CV_MIN = 0.005
BIC_MIN = 10.0
ALPHA = 0.01
LACK_OF_FIT = 1.15     # residual RMS above this multiple of the repeat noise: structure is left
EXCESS_MIN = 0.2       # with structure left, the share of the excess a named effect must explain
NEGATIVE_SIGMA = 5.0   # a compliance this many standard errors below zero is not physical (cf. sanity.P_FAR)
LACK_OF_FIT_STATED = 1.5   # the same, against the model's stated noise when the data hold no repeats
MAX_FOLDS = 10


@dataclass
class Candidate:
    """One effect tried at one place, with its evidence."""

    effect: Effect
    n_params: int
    rms_position_mm_after: float
    rms_rotation_deg_after: float
    cv_improvement: float
    delta_bic: float
    p_value: float
    criteria: dict[str, bool]
    estimate: np.ndarray            # SI, the new parameters
    std_error: np.ndarray
    contribution: np.ndarray        # (N, 6) the deflection it explains, mm / deg
    explanation: str = ""
    excess_explained: float = float("nan")   # share of the residual's excess over the noise

    named: bool = False              # significant, and explains enough of any structure left

    @property
    def physical(self) -> bool:
        """No compliance of its estimate below zero by more than NEGATIVE_SIGMA standard errors: an effect that
        deflects against the load is a misreading's (a radius, a frame), never named; a component near zero
        may fall a little below it by the noise alone."""
        return all(v >= -NEGATIVE_SIGMA * se for p, v, se in zip(self.effect.params, self.estimate, self.std_error)
                   if p.compliance)

    @property
    def significant(self) -> bool:
        c = self.criteria
        return c["cross_validation"] and (c["bic"] or c["f_test"])

    @property
    def name(self) -> str:
        return self.effect.name

    @property
    def joint(self) -> int | None:
        return self.effect.joint

    @property
    def where(self) -> str:
        """Where the effect sits, in words: 'joint 3', 'link 2' (its location key), or 'global'."""
        return f"{self.effect.location_key} {self.joint}" if self.joint is not None else "global"

    def entry(self) -> dict:
        """The YAML entry that adds this effect with its estimated parameters."""
        return _with_theta(self.effect, self.estimate).to_config()

    def add_options(self) -> dict[str, str]:
        """The options of `stiffcomp model add` the diagnosis advises for this effect (its text says them too):
        ``{"preload": "identify"}`` for an effect found off the model's static torque."""
        return {"preload": "identify"} if self.preload is not None else {}

    preload: dict | None = None      # for an effect found off the model's static torque: the model's preload entry


@dataclass
class Diagnosis:
    fit: FitResult
    ctx: Context
    worst: dict
    noise: dict | None
    candidates: list[Candidate]
    verdict: str
    message: str
    lack_of_fit: dict = field(default_factory=dict)

    @property
    def best(self) -> Candidate | None:
        return self.candidates[0] if self.candidates and self.candidates[0].named else None


def _with_theta(effect: Effect, theta: np.ndarray) -> Effect:
    e = copy.copy(effect)
    e.theta = np.asarray(theta, dtype=float)
    return e


# -- candidates ---------------------------------------------------------------------------------
def candidate_variants(model: StiffnessModel, ctx: Context) -> list[list[Effect]]:
    """Every library effect the model lacks, at every place it applies (each effect's `candidates`); each
    a list of shape variants. In reading order: joint by joint, then the links, then the global effects."""
    groups = [(k, g) for k, cls in enumerate(EFFECTS.values()) for g in cls.candidates(model, ctx)]

    def order(item):
        k, group = item
        e = group[0]
        place = 2 if e.joint is None else (0 if e.location_key == "joint" else 1)
        return place, e.joint or 0, k

    return [g for _, g in sorted(groups, key=order)]


def candidate_columns(model: StiffnessModel, ctx: Context, effect: Effect) -> np.ndarray:
    """(N, 6, Pc) deflection per unit of the effect's parameters, at the fitted model."""
    aug = StiffnessModel(model.robot, model.effects + [effect], noise=model.noise, source=model.source,
                         payload=model.payload)
    th = np.concatenate([model.theta, effect.theta])
    if effect.linear:      # closed form for its columns alone (the candidates' shapes are fixed)
        return design(aug, ctx, aug.frame_wrenches(ctx, th), th, [effect])
    return jacobian(aug, ctx, th)[:, :, len(model.theta):]


def preload_entry(model: StiffnessModel, ctx: Context, effect: Effect) -> dict | None:
    """For an axial effect found with its centre free per configuration: the model's ``preload`` entry at
    its joint, started where the centres were found (`preload_term.start_from_centres`); else None."""
    centres = getattr(effect, "free_centres", None)
    if centres is None:
        return None
    term = PreloadTerm(model.robot, effect.joint)
    term.theta = start_from_centres(model, ctx, term, centres, effect.centres_found)
    return {"joint": effect.joint, **term.to_config()}


# -- scoring ------------------------------------------------------------------------------------
class _Gram:
    """Per-fold Gram blocks of the base Jacobian and the residual, for fast nested least squares.

    ``prior``: rows (A_p, r_p) over the base parameters that join every training set and are never held
    out (a prior's, `stiffness.model.prior`)."""

    def __init__(self, A0: np.ndarray, r: np.ndarray, fold: np.ndarray,
                 prior: tuple[np.ndarray, np.ndarray] | None = None):
        self.folds = np.unique(fold)
        p0 = A0.shape[1]
        Ap, rp = prior if prior is not None else (np.zeros((0, p0)), np.zeros(0))
        self.norm0 = _norms(np.vstack([A0, Ap]))        # the data's and the prior's together: one scale
        self.A0 = A0 / self.norm0
        Ap = Ap / self.norm0
        self.Gp, self.bp, self.rrp = Ap.T @ Ap, Ap.T @ rp, float(rp @ rp)
        self.r = r
        # each fold's rows, and its slices of the base Jacobian and residual, cut once for all candidates
        self.rows = [np.nonzero(fold == k)[0] for k in self.folds]
        self.A0_f = [self.A0[i] for i in self.rows]
        self.r_f = [r[i] for i in self.rows]
        self.G00 = np.stack([a.T @ a for a in self.A0_f])
        self.b0 = np.stack([a.T @ rk for a, rk in zip(self.A0_f, self.r_f)])
        self.rr = np.array([rk @ rk for rk in self.r_f])

    def blocks(self, Xc: np.ndarray):
        X_f = [Xc[i] for i in self.rows]
        G0c = np.stack([a.T @ x for a, x in zip(self.A0_f, X_f)])
        Gcc = np.stack([x.T @ x for x in X_f])
        bc = np.stack([x.T @ rk for x, rk in zip(X_f, self.r_f)])
        M = np.concatenate([np.concatenate([self.G00, G0c], 2),
                            np.concatenate([np.swapaxes(G0c, 1, 2), Gcc], 2)], 1)
        v = np.concatenate([self.b0, bc], 1)
        return M, v

    def rss_and_cv(self, M: np.ndarray, v: np.ndarray) -> tuple[float, float, np.ndarray, np.ndarray]:
        """Full-data RSS, held-out SSE summed over folds, the solution and its (unscaled) covariance."""
        Mt, vt = M.sum(0), v.sum(0)
        p0 = len(self.bp)
        Mt[:p0, :p0] += self.Gp
        vt[:p0] += self.bp
        cov = np.linalg.pinv(Mt)
        x = cov @ vt
        rss = float(self.rr.sum() + self.rrp - vt @ x)
        sse = 0.0
        for k in range(len(self.folds)):
            xk = np.linalg.lstsq(Mt - M[k], vt - v[k], rcond=1e-12)[0]
            sse += float(self.rr[k] - 2 * xk @ v[k] + xk @ M[k] @ xk)
        return rss, sse, x, cov


def _norms(X: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(X, axis=0)
    return np.where(n > 0, n, 1.0)


def folds_by_configuration(ctx: Context) -> np.ndarray:
    """A fold id per residual entry: configurations grouped into at most MAX_FOLDS folds; a single
    configuration is cut into five blocks in time."""
    n_cfg = len(ctx.config_labels)
    if n_cfg >= 2:
        fold_of_reading = ctx.config % min(n_cfg, MAX_FOLDS)
    else:
        order = np.argsort(np.argsort(ctx.time))
        fold_of_reading = order * 5 // max(ctx.n_readings, 1)
    return np.repeat(fold_of_reading[ctx.row_reading], 6)


@dataclass
class _Base:
    """What every candidate is weighed against: the fitted model's residual and weights, its Jacobian, its
    residual sum of squares and cross-validated one, the rows used and the base parameters' count."""

    resid: np.ndarray
    wt: np.ndarray
    J0: np.ndarray
    rss0: float
    sse0: float
    n: int
    p0: int
    use: np.ndarray


def _evaluate(group, fitted: StiffnessModel, ctx: Context, gram: _Gram, base: _Base, alpha: float) -> Candidate:
    """The best variant of one candidate effect (`group`, by cross-validated error), with its evidence: what it
    explains with the base parameters re-adjusted, the F test, delta BIC and the cross-validation."""
    n_rows = base.resid.shape[0] * base.resid.shape[1]
    best = None
    for effect in group:
        X = candidate_columns(fitted, ctx, effect)
        Xw = (X * base.wt[:, :, None]).reshape(n_rows, -1)
        norm = _norms(Xw)
        M, v = gram.blocks(Xw / norm)
        rss1, sse1, x, cov = gram.rss_and_cv(M, v)
        if best is None or sse1 < best[1]:
            best = (effect, sse1, rss1, x, cov, X, norm)
    effect, sse1, rss1, x, cov, X, norm = best
    n, p0, pc = base.n, base.p0, X.shape[2]
    s2 = rss1 / max(n - p0 - pc, 1)
    est = x[p0:] / norm
    se = np.sqrt(np.clip(np.diag(cov)[p0:], 0, None) * s2) / norm
    # the deflection this effect explains, with the base parameters re-adjusted
    step0 = (x[:p0] / gram.norm0)
    contribution = np.einsum("nap,p->na", X, est) + np.einsum("nap,p->na", base.J0, step0)
    after = base.resid - contribution
    drop = max(base.rss0 - rss1, 0.0)
    fstat = (drop / pc) / (rss1 / max(n - p0 - pc, 1)) if rss1 > 0 else np.inf
    p_value = float(f_dist.sf(fstat, pc, max(n - p0 - pc, 1)))
    dbic = float(n * np.log(max(rss1, 1e-300) / base.rss0) + pc * np.log(n))
    cv_imp = float(np.clip(1.0 - sse1 / base.sse0, 0.0, 1.0)) if base.sse0 > 0 else 0.0
    criteria = {"cross_validation": cv_imp >= CV_MIN, "bic": dbic < -BIC_MIN, "f_test": p_value < alpha}
    use = base.use
    return Candidate(effect, pc, rms(after[use, :3]), rms(after[use, 3:]), cv_imp, dbic, p_value, criteria, est, se,
                     contribution, preload=preload_entry(fitted, ctx, effect))


def diagnose(model: StiffnessModel, data: Dataset, progress=None, robust: bool = True,
             prior: Prior | None = None) -> Diagnosis:
    """Fit ``model`` to ``data``, find where it fails, and rank the library effects it lacks.

    Only the measured components count. With ``robust`` (the default) the rows the fit judges gross
    errors (`stiffness.fit.gross_errors`) are left out of the fit and of every candidate's evidence; a missing effect
    repeats in every reading of a load state and is not mistaken for them. With ``prior`` (what the model
    knew before these data, `stiffness.model.prior`: a machined part sees few combinations of the parameters,
    `stiffness.part.diagnose`) the fit and every candidate's nested fit hold the base parameters to it.
    """
    say = progress or (lambda msg: None)
    need = 2 * (len(model.theta) + 6)          # the model and the largest candidate, twice over
    n_meas = int(data.measured.sum())
    if n_meas < need:
        raise DataError(f"{data.source}: too few rows to diagnose ({len(data)} rows, {n_meas} residuals); "
                        f"a model of {len(model.theta)} parameters and its candidates need at least {need}")
    say("fitting the model")
    ctx = model.context(data)
    result = fit(model, ctx, robust=robust, prior=prior)
    fitted = result.model
    resid = result.residual
    # unmeasured entries and gross errors weigh nothing: they drop out of every Gram block
    wt = result.weights
    y_w = np.nan_to_num(resid * wt).reshape(-1)
    J0 = jacobian(fitted, ctx)
    # an identified preload is held at its fit: its columns are local to each configuration, so a
    # held-out configuration cannot predict them and they would only blur the cross-validation
    held = held_preload(fitted)
    J0 = J0[:, :, ~held]
    A0 = (J0 * wt[:, :, None]).reshape(len(y_w), -1)
    rows = None
    if prior is not None:             # the prior's rows, linearised at the fit: R step = -(R theta - c)
        R, c = prior.rows(fitted.param_labels())
        rows = (R[:, ~held], -(R @ fitted.theta - c))
    gram = _Gram(A0, y_w, folds_by_configuration(ctx), rows)
    rss0, sse0, _, _ = gram.rss_and_cv(gram.G00, gram.b0)
    base = _Base(resid, wt, J0, rss0, sse0, int(np.count_nonzero(wt)), A0.shape[1], result.inlier)
    use = base.use
    variants = candidate_variants(fitted, ctx)
    alpha = ALPHA / max(len(variants), 1)
    candidates = []
    for k, group in enumerate(variants):
        say(f"trying {group[0].label} ({k + 1}/{len(variants)})")
        candidates.append(_evaluate(group, fitted, ctx, gram, base, alpha))
    noise = pure_error(ctx, np.where(use[:, None], data.deflection, np.nan))
    lof = _lack_of_fit(result, noise, model, ctx)
    structure_left = lof["worst_body"] > lof["threshold"]
    for c in candidates:
        c.excess_explained = _excess_explained(result, c, lof)
        c.named = c.significant and c.physical and (not structure_left or c.excess_explained >= EXCESS_MIN)
        c.explanation = describe(c, fitted, ctx, result)
    candidates.sort(key=lambda c: (-c.named, -c.significant, -c.cv_improvement, c.delta_bic))
    verdict, message = verdict_of(candidates, lof, result)
    # "where the model fails" in units of the noise its label names (repeats, else the stated noise)
    ref = np.array([lof["position_mm"]] * 3 + [lof["rotation_deg"]] * 3)
    return Diagnosis(result, ctx, worst(ctx, np.where(use[:, None], resid, np.nan), ref), noise, candidates,
                     verdict, message, lof)


def _lack_of_fit(result: FitResult, noise: dict | None, model: StiffnessModel, ctx: Context) -> dict:
    """Residual RMS over the noise, overall and for the worst body (position and rotation)."""
    ref = noise or {"position_mm": model.noise["position_mm"], "rotation_deg": model.noise["rotation_deg"]}
    r = np.where(result.inlier[:, None], result.residual, np.nan)
    per_body = [nanmax(rms(r[ctx.body == b, :3]) / ref["position_mm"], rms(r[ctx.body == b, 3:]) / ref["rotation_deg"])
                for b in np.unique(ctx.body)]
    return {"reference": "repeated readings" if noise else "the model's stated noise",
            "threshold": LACK_OF_FIT if noise else LACK_OF_FIT_STATED,
            "position_mm": ref["position_mm"], "rotation_deg": ref["rotation_deg"],
            "position": result.rms_position_mm / ref["position_mm"],
            "rotation": result.rms_rotation_deg / ref["rotation_deg"],
            "worst_body": nanmax(*per_body)}


def _excess_explained(result: FitResult, c: Candidate, lof: dict) -> float:
    """The share of the residual's excess over the noise (in noise units) the candidate removes."""
    ex = expl = 0.0
    for before, after, ref in ((result.rms_position_mm, c.rms_position_mm_after, lof["position_mm"]),
                               (result.rms_rotation_deg, c.rms_rotation_deg_after, lof["rotation_deg"])):
        if np.isnan(before):          # this kind was not measured
            continue
        ex += max(before**2 - ref**2, 0.0) / ref**2
        expl += (before**2 - after**2) / ref**2
    return float(np.clip(expl / ex, 0.0, 1.0)) if ex > 0 else 1.0
