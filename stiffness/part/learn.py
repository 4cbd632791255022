"""Learn from parts: each machined part is one more measurement of the same model (docs/part.md).

A part's points, read against the trace of its cut (`stiffness.part.rows`), are rows of a campaign that
measure one component each, the deflection along the surface normal: e = n . dX(q, W; theta), linear in
the model's compliances through the joints and the wrench of the moment the tool passed. The project's
one identification code fits them (`identify.fit`), with the model's earlier information as the prior
(`stiffness.model.prior`): the covariance its campaign fit stored, a campaign given again, or, for a model no
campaign identified, its own values within a stated fraction. So a part moves the parameter combinations
it determines better than the prior did, and leaves the others where they were; `Learned.determined`
names them. Compliances are bounded at zero as `fit --nonnegative` bounds them, and a model that is still
not physical is refused, as the service refuses it.

A part without a datum (``--best-fit``) adds its placement to the fit, a shift in its plane that absorbs any
constant shift of its contour, and with it what the model would have said of one.

Where the parts leave more than the model's noise explains (`sanity`), they are learned once more with one
distance along every normal a part (`RadiusOffset`): a radius that is off puts every point that far off along
its normal, which the compliances absorb only in part, and only the offset gives back (`Offsets`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..data.campaign import Context
from ..data.measurements import Dataset
from ..effects.base import Effect, Param
from ..errors import ConfigError, StiffnessError
from ..fit.identify import fit, jacobian
from ..fit.result import FitResult
from ..model.prior import Prior, covariance_entry
from ..model.stiffness_model import StiffnessModel
from ..units import M_TO_MM
from .contour import plane_basis
from .left_out import GROSS, LeftOut, fit_account, left_out_lines, rms_kept_and_all
from .rows import PartRows
from .sanity import problems, residual_exceeds
from .timing import when_made

DETERMINED = 1.0        # a combination is the parts' when their information exceeds the prior's by this factor
SHOWN = 6               # combinations listed
PLACEMENT_M = 0.001     # the best fit placed a part; learning refines its shift within this (1 sigma)
OFFSET_M = 0.005        # a radius off by up to a few mm: the offset's weak prior (1 sigma)


class PartNuisance(Effect):
    """What learning from parts fits beside the model and removes again, a set of parameters for each part
    (``labels``) within a weak prior (``loose``, SI): not a physical effect, not in the library, refused in a
    model file."""

    per_joint = False
    joints = ()

    def __init__(self, parts: list[PartRows], params: list[Param], loose_m: float):
        self.labels = [p.label for p in parts]
        super().__init__(params, np.zeros(len(params)), None)
        self.loose = np.full(len(params), loose_m)

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> PartNuisance:
        raise ConfigError(f"{where}: {cls.name} is not a model effect (it exists only while learning from parts)")

    @staticmethod
    def rows(ctx: Context, label: str) -> np.ndarray:
        """The readings of the part ``label``."""
        return ctx.config == ctx.config_labels.index(label)


class Placement(PartNuisance):
    """The placement of each part without a datum, as far as learning refines it: a shift in the plane across
    the tool axis (two numbers a part), applied to everything at the base site. The best fit
    (`rows.read_against`) turned and shifted the part already; along a circle's normal a turn about any
    point is a shift and nothing else, so refining it too would only trade the two. `learn` adds it for a
    ``--best-fit`` part.

    Parameters
    ----------
    parts : the parts, each with its label, its tool axis and its points (`PartRows`)
    """

    name = "placement"

    def __init__(self, parts: list[PartRows]):
        self.frames = []
        for p in parts:
            a = p.axis.mean(axis=0)
            self.frames.append(plane_basis(a / np.linalg.norm(a)))
        params = []
        for p in parts:
            params += [Param(f"{_key(p.label)}_u_mm", "mm", 1e-4, M_TO_MM),
                       Param(f"{_key(p.label)}_v_mm", "mm", 1e-4, M_TO_MM)]
        super().__init__(parts, params, PLACEMENT_M)

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        B = self.zeros(ctx, 2 * len(self.labels))
        for i, (lab, (e1, e2)) in enumerate(zip(self.labels, self.frames)):
            rows = self.rows(ctx, lab)
            B[rows, 2 * i, 0, :3] = e1
            B[rows, 2 * i + 1, 0, :3] = e2
        return B


class RadiusOffset(PartNuisance):
    """One distance along every normal a part, as a radius off by that much puts each point (a stylus radius too
    large, or a tool radius too small, by d moves every point d toward the wall): a parameter a part, its basis
    the normal of each of its points (``normals``, base axes, one a dataset row). `learn` adds it to learn the
    parts once more when they leave more than the noise."""

    name = "radius_offset"

    def __init__(self, parts: list[PartRows], normals: np.ndarray):
        self.normals = normals
        super().__init__(parts, [Param(f"{_key(p.label)}_offset_mm", "mm", 1e-4, M_TO_MM) for p in parts], OFFSET_M)

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        B = self.zeros(ctx, len(self.labels))
        for i, lab in enumerate(self.labels):
            rows = self.rows(ctx, lab)
            B[rows, i, 0, :3] = self.normals[rows]
        return B


@dataclass
class Offsets:
    """The parts learned once more with a `RadiusOffset`: each part's offset along its normals and its standard
    error (mm, by label), and the RMS the parts then leave over the points kept (mm)."""

    offset_mm: dict[str, float]
    std_mm: dict[str, float]
    after_mm: float


def _key(label: str) -> str:
    return "".join(ch if ch.isalnum() else "_" for ch in label)


@dataclass
class Combination:
    """A direction in the parameters the parts determine: its weights, its information over the prior's,
    and how far the learning moved along it in the prior's standard deviations."""

    weights: dict[str, float]
    ratio: float
    moved_sigma: float

    def text(self) -> str:
        terms = sorted(self.weights.items(), key=lambda kv: -abs(kv[1]))[:4]
        body = " ".join(f"{w:+.2f} {lab}" for lab, w in terms)
        more = f" (+{len(self.weights) - 4} more)" if len(self.weights) > 4 else ""
        return (f"{body}{more}: the parts know it {self.ratio:.3g} x better than the prior; moved "
                f"{self.moved_sigma:+.2f} prior sigma")


@dataclass
class Learned:
    """What `learn` did: the new model, its fit, and what the parts told."""

    model: StiffnessModel
    fit: FitResult
    prior: Prior
    parts: list[PartRows]
    determined: list[Combination]
    n_params: int
    before_mm: float             # RMS of the parts' deviation the model leaves, before and after, over the
    after_mm: float              # points the fit kept (not its gross errors)
    changes: list[tuple[str, float, float]]      # (label, before, after) SI, largest relative first
    notes: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)     # why it should not be written (`sanity`)
    before_all_mm: float = float("nan")       # the same over every point read, the fit's gross errors too
    after_all_mm: float = float("nan")
    left_out: list[LeftOut] = field(default_factory=list)  # the points no figure holds: the parts' and the fit's
    data: Dataset | None = None               # the rows fitted (the parts' points and the trace between them)
    missed_before: np.ndarray | None = None   # (rows,) mm, what the model missed along the normal before learning;
                                              # after: fit.residual[:, 0]; the text's RMS and the report's plot
                                              # both read these two
    best_fit: bool = False                    # the parts were placed by a best fit, not by their frames
    offsets: Offsets | None = None            # learned again with one offset a part, where the parts left more
                                              # than the noise (`sanity`)

    @property
    def points_kept(self) -> int:
        """The points the figures hold: read against their traces and kept by the fit."""
        return sum(len(p.used) for p in self.parts) - len(self.left_out)

    def _with_gross(self) -> str:
        n = sum(x.why == GROSS for x in self.left_out)
        return (f"; with the {n} the fit left out: {self.before_all_mm:.4f} mm before, {self.after_all_mm:.4f} mm "
                "after" if n else "")

    def lines(self) -> list[str]:
        n_pts = self.points_kept
        left = f" ({len(self.left_out)} left out, named below)" if self.left_out else ""
        out = [f"learned from {len(self.parts)} part(s), {n_pts} points{left}: "
               + "; ".join(f"{p.label}: {p.part.source} against {p.trace.source}" for p in self.parts),
               f"prior: {self.prior.source}",
               (f"the parts' normal deviation the model leaves, over the {n_pts} points kept: RMS "
                f"{self.before_mm:.4f} mm before, {self.after_mm:.4f} mm after" + self._with_gross())]
        k = len(self.determined)
        out.append(f"the parts determine {k} combination(s) of the model's {self.n_params} parameters better than "
                   f"the prior; the other {self.n_params - k} stay at the prior"
                   + (":" if k else " (nothing was learned)"))
        out += [f"  {i + 1}. {c.text()}" for i, c in enumerate(self.determined[:SHOWN])]
        if k > SHOWN:
            out.append(f"  ... and {k - SHOWN} more")
        if self.changes:
            out.append("largest changes: " + ", ".join(
                f"{lab} {100 * (b1 / b0 - 1):+.0f} %" for lab, b0, b1 in self.changes[:5]))
        out += [f"warning: {w}" for w in self.fit.warnings if "the non-negative bound" in w]
        out += self.notes + left_out_lines([x for x in self.left_out if x.why == GROSS])
        out += [f"problem: {p}" for p in self.problems]
        return out


def learn(model: StiffnessModel, parts: list[PartRows], prior: Prior, best_fit: bool = False,
          progress=None) -> Learned:
    """Fit ``model`` to the points of ``parts`` with ``prior`` (module docstring); refuses a model that is
    not physical (StiffnessError naming the parameter)."""
    say = progress or (lambda msg: None)
    if not parts:
        raise StiffnessError("learning needs at least one part (a trace and its part's measurement)")
    labels = [p.label for p in parts]
    if len(set(labels)) != len(labels):
        raise StiffnessError(f"two parts share the label {labels}: each part needs its own")
    parts = [when_made(p, model) for p in parts]
    data = _concat([p.dataset(model.robot, model.input_map()) for p in parts])
    work, fit_prior = _with_nuisance(model, prior, [Placement(parts)] if best_fit else [])
    ctx = work.context(data)
    pred_before = work.predict(ctx)
    say(f"fitting {len(model.theta)} parameters to {int(data.measured.sum())} points with the prior")
    result = fit(work, ctx, prior=fit_prior, nonnegative=True)
    learned = _without_placement(result, model) if best_fit else result.model
    problem = learned.unphysical()
    if problem:
        raise StiffnessError(f"refused: {problem}; the parts pull the model where no robot is (the service "
                             "refuses such a model too): check the trace and the part belong together")
    say("naming what the parts determine")
    combos = _determined(result, work, ctx, prior, len(model.theta))
    left_out, after, after_all = fit_account(parts, data, result)
    before, before_all = rms_kept_and_all(data.deflection[:, 0] - pred_before[:, 0], data.measured[:, 0],
                                          result.outlier)
    labs = model.param_labels()
    ch = [(lab, b0, b1) for lab, b0, b1 in zip(labs, model.theta, learned.theta) if b0 != 0 and b1 != b0]
    ch.sort(key=lambda c: -abs(c[2] / c[1] - 1))
    notes = [n for p in parts for n in p.notes]
    out = Learned(learned, result, prior, parts, combos, len(model.theta), before, after, ch, notes,
                  before_all_mm=before_all, after_all_mm=after_all, data=data,
                  missed_before=data.deflection[:, 0] - pred_before[:, 0],
                  left_out=left_out, best_fit=best_fit)
    if residual_exceeds(out, model):
        say("learning again with one offset along the normals a part")
        out.offsets = _offsets(model, parts, data, prior, best_fit)
    out.problems = problems(out, model, data)
    return out


def _with_nuisance(model: StiffnessModel, prior: Prior, extra: list[PartNuisance]) -> tuple[StiffnessModel, Prior]:
    """``model`` with the nuisance effects ``extra`` (`Placement`, `RadiusOffset`) and ``prior`` with their weak
    priors."""
    if not extra:
        return model, prior
    work = StiffnessModel(model.robot, model.effects + extra, model.name, model.description, model.robot_ref,
                          model.noise, model.source, model.payload)
    return work, prior.with_more(work.param_labels()[len(model.theta):], np.concatenate([e.loose for e in extra]))


def _offsets(model: StiffnessModel, parts: list[PartRows], data: Dataset, prior: Prior, best_fit: bool) -> Offsets:
    """The parts learned once more with one `RadiusOffset` a part (and their placements with --best-fit)."""
    offset = RadiusOffset(parts, data.axes[:, 0])
    work, fit_prior = _with_nuisance(model, prior, ([Placement(parts)] if best_fit else []) + [offset])
    result = fit(work, work.context(data), prior=fit_prior, nonnegative=True)
    k = len(offset.labels)
    value, std = result.model.theta[-k:], np.sqrt(np.diag(result.covariance))[-k:]
    _, after, _ = fit_account(parts, data, result)
    return Offsets({lab: M_TO_MM * float(v) for lab, v in zip(offset.labels, value)},
                   {lab: M_TO_MM * float(v) for lab, v in zip(offset.labels, std)}, after)


def _concat(sets: list[Dataset]) -> Dataset:
    cat = [np.concatenate([getattr(d, a) for d in sets]) for a in ("time_s", "config", "q_deg", "wrench", "body",
                                                                  "deflection", "line", "axes")]
    return Dataset(*cat[:7], source=", ".join(d.source for d in sets), axes=cat[7])


def _without_placement(result: FitResult, model: StiffnessModel) -> StiffnessModel:
    """The learned model without the placement, its covariance restricted to the model's own parameters."""
    out = model.copy()
    P = len(model.theta)
    out.theta = result.model.theta[:P]
    for e, e_fit in zip(out.effects, result.model.effects):
        e.std_error = e_fit.std_error
    out.covariance = covariance_entry(out, result.covariance[:P, :P], result.model.covariance["source"])
    return out


def _determined(result: FitResult, work: StiffnessModel, ctx: Context, prior: Prior, P: int) -> list[Combination]:
    """The combinations of the model's P parameters whose information from the parts exceeds the prior's:
    the generalised eigenvectors of the two informations, in the prior's standard deviations."""
    J = jacobian(result.model, ctx)
    Jw = (J * result.weights[:, :, None]).reshape(-1, J.shape[2])[:, :P]
    s2 = max(float(np.nansum((result.residual * result.weights) ** 2)) / max(np.count_nonzero(result.weights) - P, 1),
             1e-300)
    F_data = Jw.T @ Jw / s2
    labels = work.param_labels()[:P]
    R, _ = prior.rows(labels)
    F_prior = R.T @ R
    known = np.diag(F_prior) > 0
    if not known.any():
        return []
    idx = np.nonzero(known)[0]
    L = np.linalg.cholesky(F_prior[np.ix_(idx, idx)] + 1e-12 * np.eye(len(idx)) * np.trace(F_prior) / len(idx))
    Li = np.linalg.inv(L)
    M = Li @ F_data[np.ix_(idx, idx)] @ Li.T
    lam, U = np.linalg.eigh((M + M.T) / 2)
    order = np.argsort(lam)[::-1]
    moved = result.model.theta[:P][idx] - _prior_mean(prior, labels)[idx]
    out = []
    for k in order:
        if lam[k] < DETERMINED:
            break
        u = U[:, k]
        v = Li.T @ u                       # the direction in the parameters (the prior's sigma as unit)
        sd = 1.0 / np.sqrt(np.diag(F_prior)[idx])
        w = v / sd
        w /= np.max(np.abs(w))
        out.append(Combination({labels[i]: float(x) for i, x in zip(idx, w) if abs(x) > 0.05}, float(lam[k]),
                               float(u @ (L.T @ moved))))
    return out


def _prior_mean(prior: Prior, labels: list[str]) -> np.ndarray:
    where = {lab: k for k, lab in enumerate(prior.labels)}
    return np.array([prior.mean[where[lab]] if lab in where else 0.0 for lab in labels])
