"""Whether what `part learn` learned from parts can be believed: the checks that keep a misplaced part from
becoming a model in silence (`stiffcomp part learn` writes nothing when one fails, unless ``--force``).

A part's points read against its trace (`stiffness.part.rows`) are e = n . dX + probe noise, and the model
with its prior (`stiffness.model.prior`) is the account of n . dX. So the learned model has two things to answer for:

* **the residual the parts leave** against what the model's stated noise explains (``noise.position_mm``,
  the weight every row of the fit carries). With n points and k combinations the parts determined, the
  mean square residual of pure noise is sigma^2 chi2(n - k) / (n - k); beyond its upper tail at P_FAR the
  parts hold something the model cannot make: a part not where its ``part_frame`` says (a shift of the
  points, n . d along each normal), a trace that is not the part's, or an effect the model lacks;
* **how far the parts pulled the model** against what its prior allows. Along each combination the parts
  determine, the move in the prior's standard deviations has, when the prior is right, a variance
  lambda / (1 + lambda) < 1 (lambda: the parts' information over the prior's); the sum of their squares is
  at most chi2(k). Beyond its tail at P_FAR the parts ask for a robot the prior says is not there: most often
  a wrong ``tool_radius_mm`` (a radius off by d puts every point d off along its normal, a constant the
  compliances then absorb with changes of hundreds of per cent).

Two more: parts that determine nothing (the model would only move within its prior: nothing was learned),
and an input model that already held negative compliances (the non-negative bound sets them to 0, a change
no part made).

P_FAR is the one-sided tail of a normal beyond 5 standard deviations (2.9e-7): "far" in the sense physics
uses for a discovery, so that a sound part is refused about once in three million.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2, norm

from .suspects import placing_keys

P_FAR = float(norm.sf(5.0))
HINT_SHARE = 0.5     # a shift of the part is named as the likely cause when it explains this share of the residual
RADIUS_MARGIN = 0.1  # ... and a radius when it alone explains within this share of what the two together do


def problems(learned, start, data) -> list[str]:
    """What keeps ``learned`` (`learn.Learned`) from being written, in words with the likely cause;
    empty when nothing does. ``start``: the model it was learned from; ``data``: the parts' rows it was fitted
    to (`PartRows.dataset`, its rows those of ``learned.fit``)."""
    return [text for _, text in checks(learned, start, data)]


def misread(learned, start, data) -> list[str]:
    """The problems that say the parts were read wrong, not that the model lacks something: all but a residual
    that no radius or shift of the points explains, which is what `stiffcomp part diagnose` is for. A diagnosis
    from parts with one of these would name an effect for a misread file."""
    return [text for kind, text in checks(learned, start, data) if kind != RESIDUAL]


RESIDUAL, PLACEMENT, MOVED, NOTHING, INPUT = "residual", "placement", "moved", "nothing learned", "input model"


def checks(learned, start, data) -> list[tuple[str, str]]:
    """Each failed check as (kind, words): the kinds above."""
    out = []
    residual = _residual(learned, start, data)
    if residual:
        out.append(residual)
    moved = _moved(learned)
    if moved:
        out.append((MOVED, moved))
    if not learned.determined:
        out.append((NOTHING, (f"the parts determine no combination of the model's {learned.n_params} parameters "
                              f"better than its prior ({learned.prior.source}): nothing was learned, and whatever "
                              "moved, moved within the prior. Likely the prior already holds what these parts tell "
                              "(a campaign's covariance), or the parts are too few or too lightly loaded to show "
                              "the compliances")))
    negative = [lab for lab, p, v in zip(start.param_labels(), _params(start), start.theta) if p.compliance and v < 0]
    if negative:
        out.append((INPUT, (f"the input model {start.source} holds {len(negative)} negative compliance(s) "
                            f"({', '.join(negative[:4])}{' ...' if len(negative) > 4 else ''}): not physical (the "
                            "service refuses such a model), and the non-negative bound set them to 0, a change no "
                            "part made; fit the model with `stiffcomp fit --nonnegative` first")))
    return out


def _params(model):
    return [p for e in model.effects for p in e.params]


def _keys(learned) -> tuple[str, str, bool]:
    """The radius and frame keys of the parts (`suspects.placing_keys`), and whether they are probe logs."""
    keys = {placing_keys(p.part) for p in learned.parts}
    radius, frame = (" or ".join(dict.fromkeys(k[i] for k in keys)) for i in (0, 1))
    return radius, frame, all(p.part.probed for p in learned.parts)


def residual_exceeds(learned, start) -> bool:
    """Whether the parts leave more after learning than the model's stated noise explains (`_residual`)."""
    rms, limit, _ = _residual_and_limit(learned, start)
    return rms > limit


def _residual_and_limit(learned, start) -> tuple[float, float, int]:
    """The parts' RMS after learning over the fit's inliers, the most the stated noise explains at P_FAR, and
    the points (mm, mm, n); (0, inf, n) where the points do not outnumber the combinations determined."""
    fit = learned.fit
    r = fit.residual[fit.inlier & np.isfinite(fit.residual[:, 0]), 0]
    n, k = len(r), len(learned.determined)
    if n <= k:
        return 0.0, float("inf"), n
    limit = float(start.noise["position_mm"]) * float(np.sqrt(chi2.isf(P_FAR, n - k) / (n - k)))
    return float(np.sqrt(np.mean(r ** 2))), limit, n


def _residual(learned, start, data) -> tuple[str, str] | None:
    """The parts' residual after learning against the stated noise (the module's docstring), with the radius or
    the shift of the points that explains it when one does (kind PLACEMENT; RESIDUAL when none does)."""
    rms, limit, n = _residual_and_limit(learned, start)
    if rms <= limit:
        return None
    fit = learned.fit
    rows = fit.inlier & np.isfinite(fit.residual[:, 0])
    radius, frame, probed = _keys(learned)
    sigma = float(start.noise["position_mm"])
    hint = (_placement_hint(learned, data, rows, fit.residual[rows, 0])
            or _offset_hint(learned, rms, limit, n, sigma))
    head = (f"the parts leave RMS {rms:.4f} mm after learning, where the model's stated noise (noise.position_mm "
            f"{sigma:g} mm) explains at most {limit:.4f} mm over {n} points: the parts "
            "do not fit this model. ")
    if hint:
        return PLACEMENT, head + hint
    placed = "" if probed or learned.best_fit else f"a part not where its {frame} says (or place it by --best-fit), "
    return RESIDUAL, head + (f"Likely {placed}a wrong {radius}, a trace that is not the part's, a probe noisier "
                             "than noise.position_mm, or an effect the model lacks (`stiffcomp part diagnose`)")


def _placement_hint(learned, data, rows: np.ndarray, r: np.ndarray) -> str:
    """'Likely ...' when one distance along every normal (a radius off) or one rigid shift of each part's points
    (n . d along each normal, with the distance) explains at least HINT_SHARE of the residual ``r`` of ``rows``;
    '' otherwise. The radius is named when it alone explains HINT_SHARE and within RADIUS_MARGIN of what the
    radius and the shift explain together."""
    normal = data.axes[rows, 0]
    config = np.asarray(data.config)[rows]
    by_label = {p.label: p.part for p in learned.parts}
    total = max(float(np.sum(r ** 2)), 1e-300)
    both_left, const_left, fixes, shifts = r.copy(), r.copy(), [], []
    for lab in dict.fromkeys(config):
        m = config == lab
        A = np.column_stack([normal[m], np.ones(int(m.sum()))])
        x = np.linalg.lstsq(A, r[m], rcond=None)[0]
        both_left[m] = r[m] - A @ x
        c = float(np.mean(r[m]))
        const_left[m] = r[m] - c
        fixes.append(_radius_fix(by_label[lab], lab, c))
        shifts.append(f"{lab} ({', '.join(f'{v:+.2f}' for v in x[:3])}) mm")
    both = 1.0 - float(np.sum(both_left ** 2)) / total
    const = 1.0 - float(np.sum(const_left ** 2)) / total
    radius, frame, probed = _keys(learned)
    if const >= HINT_SHARE and const >= both - RADIUS_MARGIN:
        return (f"Likely a wrong {radius}: one distance along every normal explains {100 * const:.0f} % of what is "
                f"left ({'; '.join(fixes)}); else a wrong {frame}, or an effect the model lacks")
    if both < HINT_SHARE:
        return ""
    if learned.best_fit:
        return (f"Likely a wrong {radius}: after the best fit placed each part, one shift of its points still "
                f"explains {100 * both:.0f} % of what is left ({'; '.join(shifts)}), as a radius that is off leaves "
                "a part best fitted to an arc; else a trace that is not the part's, or an effect the model lacks")
    if probed:
        return (f"Likely a wrong probe_frame (the stylus centre in the flange frame) or stylus_radius_mm: one "
                f"shift of the touches in the robot's base explains {100 * both:.0f} % of what is left "
                f"({'; '.join(shifts)}); else a trace that is not the probe's cut, or an effect the model lacks")
    return (f"Likely a part not where its part_frame says: one shift of its points in the robot's base explains "
            f"{100 * both:.0f} % of what is left ({'; '.join(shifts)}: correct part_frame's xyz_mm by minus that), "
            f"or place it by --best-fit; else a wrong {radius}, a trace that is not the part's, or an effect the "
            "model lacks")


def _offset_hint(learned, rms: float, limit: float, n: int, sigma: float) -> str:
    """'Likely a wrong radius ...' when the parts learned once more with one distance along every normal a part
    (`learn.Offsets`) leave at most ``limit`` (what the noise ``sigma`` explains) where they left ``rms`` over
    ``n`` points, and the distances' share of that is far: the drop in chi-square, n (rms^2 - after^2) / sigma^2,
    beyond its tail at P_FAR for one distance a part (a likelihood ratio; a distance's own standard error
    counts what the compliances could also have absorbed, so it says less); '' otherwise."""
    got = learned.offsets
    if got is None or got.after_mm > limit:
        return ""
    if n * (rms ** 2 - got.after_mm ** 2) / sigma ** 2 <= chi2.isf(P_FAR, len(got.offset_mm)):
        return ""
    by_label = {p.label: p.part for p in learned.parts}
    radius, frame, _ = _keys(learned)
    return (f"Likely a wrong {radius}: learned once more with one distance along every normal a part, the parts "
            f"leave RMS {got.after_mm:.4f} mm, within what the noise explains ("
            + "; ".join(_radius_fix(by_label[lab], lab, v) for lab, v in got.offset_mm.items())
            + "; the compliances share such a distance, so its size is uncertain); else a wrong "
            f"{frame}, or an effect the model lacks")


def _radius_fix(part, label: str, c: float) -> str:
    """'part 1: every point +0.48 mm off; stylus_radius_mm 2 would be 1.52' for a constant residual ``c`` (mm).
    A probe's point lies (r_s - v tau) along the approach, so a stylus radius too large by D moves every point D
    toward the wall (the residual +D); the wall is the tool radius off the tool centre's path, so a tool radius
    too large by D leaves every point D short of it (the residual -D)."""
    tool = f"tool_radius_mm {part.tool_radius_mm:g} would be {part.tool_radius_mm + c:.3g}"
    if part.probed:
        return (f"{label}: every point {c:+.3f} mm off; stylus_radius_mm {part.stylus_radius_mm:g} would be "
                f"{part.stylus_radius_mm - c:.3g}, or {tool}")
    return f"{label}: every point {c:+.3f} mm off; {tool}"


def _moved(learned) -> str:
    """How far the parts pulled the model along what they determine, against the prior (module docstring)."""
    k = len(learned.determined)
    if not k:
        return ""
    pulled = float(np.sqrt(sum(c.moved_sigma ** 2 for c in learned.determined)))
    allowed = float(np.sqrt(chi2.isf(P_FAR, k)))
    if pulled <= allowed:
        return ""
    radius, frame, probed = _keys(learned)
    changes = ", ".join(f"{lab} {100 * (b1 / b0 - 1):+.0f} %" for lab, b0, b1 in learned.changes[:2])
    where = (f"a {frame} that is off" if probed else "a trace that is not the part's" if learned.best_fit else
             f"a part not where its {frame} says")
    return (f"the parts pull the model {pulled:.1f} prior sigma from its values along the {k} combination(s) "
            f"they determine, where its prior allows {allowed:.1f} ({changes}): the parts' deviations are not "
            f"deflections this robot makes. Likely a wrong {radius} (a radius off by d puts every point d "
            f"off along its normal, which the compliances then absorb), {where}, or a prior that is too tight")
