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

P_FAR = float(norm.sf(5.0))
HINT_SHARE = 0.5     # a shift of the part is named as the likely cause when it explains this share of the residual


def problems(learned, start, data) -> list[str]:
    """What keeps ``learned`` (`learn.Learned`) from being written, in words with the likely cause;
    empty when nothing does. ``start``: the model it was learned from; ``data``: the parts' rows it was fitted
    to (`PartRows.dataset`, its rows those of ``learned.fit``)."""
    out = []
    residual = _residual(learned, start, data)
    if residual:
        out.append(residual)
    moved = _moved(learned)
    if moved:
        out.append(moved)
    if not learned.determined:
        out.append(f"the parts determine no combination of the model's {learned.n_params} parameters better "
                   f"than its prior ({learned.prior.source}): nothing was learned, and whatever moved, moved "
                   "within the prior. Likely the prior already holds what these parts tell (a campaign's "
                   "covariance), or the parts are too few or too lightly loaded to show the compliances")
    negative = [lab for lab, p, v in zip(start.param_labels(), _params(start), start.theta) if p.compliance and v < 0]
    if negative:
        out.append(f"the input model {start.source} holds {len(negative)} negative compliance(s) "
                   f"({', '.join(negative[:4])}{' ...' if len(negative) > 4 else ''}): not physical (the service "
                   "refuses such a model), and the non-negative bound set them to 0, a change no part made; fit "
                   "the model with `stiffcomp fit --nonnegative` first")
    return out


def _params(model):
    return [p for e in model.effects for p in e.params]


def _residual(learned, start, data) -> str:
    """The parts' residual after learning against the stated noise (the module's docstring), with the shift
    of the part that explains it when one does."""
    fit = learned.fit
    rows = fit.inlier & np.isfinite(fit.residual[:, 0])
    r = fit.residual[rows, 0]
    n, k = len(r), len(learned.determined)
    sigma = float(start.noise["position_mm"])
    if n <= k:
        return ""
    limit = sigma * float(np.sqrt(chi2.isf(P_FAR, n - k) / (n - k)))
    rms = float(np.sqrt(np.mean(r ** 2)))
    if rms <= limit:
        return ""
    hint = _shift_hint(data, rows, r)
    return (f"the parts leave RMS {rms:.4f} mm after learning, where the model's stated noise (noise.position_mm "
            f"{sigma:g} mm) explains at most {limit:.4f} mm over {n} points: the parts do not fit this model. "
            f"Likely a part not where its part_frame says{hint}, or place it by --best-fit; else a wrong "
            "tool_radius_mm, a trace that is not the part's, a probe noisier than noise.position_mm, or an effect "
            "the model lacks (`stiffcomp part diagnose`)")


def _shift_hint(data, rows: np.ndarray, r: np.ndarray) -> str:
    """' (a shift of its points ... explains N % ...)' when one rigid shift d of each part's points (n . d along
    each normal, and a constant) explains at least HINT_SHARE of the residual ``r`` of ``rows``; '' otherwise."""
    normal = data.axes[rows, 0]
    config = np.asarray(data.config)[rows]
    shifts, left = [], r.copy()
    for lab in dict.fromkeys(config):
        m = config == lab
        A = np.column_stack([normal[m], np.ones(int(m.sum()))])
        x = np.linalg.lstsq(A, r[m], rcond=None)[0]
        left[m] = r[m] - A @ x
        shifts.append((lab, x[:3]))
    share = 1.0 - float(np.sum(left ** 2) / max(float(np.sum(r ** 2)), 1e-300))
    if share < HINT_SHARE:
        return ""
    where = "; ".join(f"{lab} ({', '.join(f'{v:+.2f}' for v in d)}) mm" for lab, d in shifts)
    return (f" (one shift of its points in the robot's base explains {100 * share:.0f} % of what is left, "
            f"{where}: correct part_frame's xyz_mm by minus that)")


def _moved(learned) -> str:
    """How far the parts pulled the model along what they determine, against the prior (module docstring)."""
    k = len(learned.determined)
    if not k:
        return ""
    pulled = float(np.sqrt(sum(c.moved_sigma ** 2 for c in learned.determined)))
    allowed = float(np.sqrt(chi2.isf(P_FAR, k)))
    if pulled <= allowed:
        return ""
    changes = ", ".join(f"{lab} {100 * (b1 / b0 - 1):+.0f} %" for lab, b0, b1 in learned.changes[:2])
    return (f"the parts pull the model {pulled:.1f} prior sigma from its values along the {k} combination(s) "
            f"they determine, where its prior allows {allowed:.1f} ({changes}): the parts' deviations are not "
            "deflections this robot makes. Likely a wrong tool_radius_mm (a radius off by d puts every point d "
            "off along its normal, which the compliances then absorb), a part not where its part_frame says, or "
            "a prior that is too tight")
