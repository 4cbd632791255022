"""Diagnose from the part: which effect the model misses, read from a machined part and the trace of its cut
(`stiffcomp part diagnose`, docs/part.md).

The part's points are a campaign of one configuration measuring one component each (`stiffness.part.rows`),
so the project's diagnosis runs on them as it runs on a campaign (`stiffness.diagnose.discovery`): every library
effect the model lacks, through each effect's own ``candidates``, judged by cross-validation over blocks of
the contour, BIC and an F-test. A part sees only a few combinations of the model's parameters, so the model's
prior holds the rest (`stiffness.model.prior`), in the fit and in every candidate's nested fit.

What the campaign's diagnosis says about a configuration, this one says about the contour: where along it
the named effect shows. An effect on a joint's axis that switches with the direction of the joint's torque
(its evidence plot is the torque's branches, hysteresis) shows as a step after each reversal of that torque,
where its own loading state passes the middle of its branches (a breakaway and a transition torque after the
turn: 10-20 deg along the paper's circle); one that acts around zero torque (backlash, a soft zone) where the
torque crosses zero; any other along the whole contour, with the load.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.measurements import COMPONENTS, Dataset
from ..diagnose.discovery import Candidate, Diagnosis, diagnose
from ..effects.axial import joint_torque
from ..errors import DataError
from ..model.prior import Prior
from ..model.stiffness_model import StiffnessModel
from .compare import at_points
from .learn import _concat, learn
from .rows import PartRows
from .sanity import misread
from .timing import when_made

PART_COMPONENTS = ("normal", "along the contour", "along the tool axis", "about the normal",
                   "about the contour", "about the tool axis")     # a part row's axes (n, a x n, a)
REVERSAL_FRACTION = 0.05     # a torque reversal counts once the torque moved back by this share of its range


@dataclass
class PartDiagnosis:
    """The diagnosis of one or more parts and, for the named effect, where along the contour it shows."""

    diagnosis: Diagnosis
    parts: list[PartRows]
    data: Dataset
    where: str = ""                 # "a step at 104, 290 deg along the contour, where ..."
    marks_deg: list[float] | None = None

    @property
    def message(self) -> str:
        return self.diagnosis.message + (f" Along the contour it shows as {self.where}." if self.where else "")


def diagnose_parts(model: StiffnessModel, parts: list[PartRows], prior: Prior, progress=None,
                   best_fit: bool = False) -> PartDiagnosis:
    """Run the diagnosis on the parts' points with ``prior``; name where the best candidate shows.

    First the parts go through every check `part learn` runs (`sanity`): parts that say they were read wrong
    (a radius or a frame that explains the residual, a pull beyond the prior, nothing determined) are refused,
    naming the likeliest cause, before any effect is named; the residual that no reading explains is the one
    the diagnosis is for. ``best_fit``: the parts were placed by a best fit (`part learn --best-fit`)."""
    read = parts
    parts = [when_made(p, model) for p in parts]
    data = _concat([p.dataset(model.robot, model.input_map()) for p in parts])
    need = 2 * (len(model.theta) + 6)
    if int(data.measured.sum()) < need:
        raise DataError(f"{data.source}: {int(data.measured.sum())} points; the diagnosis of a model of "
                        f"{len(model.theta)} parameters and its candidates needs at least {need}")
    (progress or (lambda msg: None))("checking the parts as part learn does")
    learned = learn(model, read, prior, best_fit)
    wrong = misread(learned, model, learned.data)
    if wrong:
        more = f" ({len(wrong) - 1} more: `stiffcomp part learn` lists them)" if len(wrong) > 1 else ""
        raise DataError(f"{', '.join(dict.fromkeys(p.part.source for p in parts))}: not diagnosed, the parts read "
                        f"wrong and `part learn` refuses them too: {wrong[0]}{more}")
    d = diagnose(model, data, progress, prior=prior)
    d.worst = in_part_axes(d.worst)
    out = PartDiagnosis(d, parts, data)
    if d.best is not None:
        out.where, out.marks_deg = where_it_shows(d.best, parts[0], d.fit.model)
    return out


def in_part_axes(worst: dict) -> dict:
    """The diagnosis' "where the model fails" with its components named in a part row's own axes (the normal,
    along the contour: tool axis x normal, the tool axis; `PartRows.dataset`), not the base's dx, dy, dz; a
    part measures the normal alone."""
    name = dict(zip(COMPONENTS, PART_COMPONENTS))
    scores = dict(worst["scores"], component={name[k]: v for k, v in worst["scores"]["component"].items()})
    return dict(worst, component=name[worst["component"]], scores=scores)


def where_it_shows(c: Candidate, rows: PartRows, model: StiffnessModel) -> tuple[str, list[float]]:
    """Words for where candidate ``c`` shows along a part's contour, and the angles (deg) to mark there.

    An effect that switches with the direction of the torque (hysteresis) steps where its own loading state
    passes the middle of its two branches: after the torque turned, by the breakaway and the transition
    torque, through the low-pass the joint follows (`effects.hysteresis`); the text names both. One at zero
    torque steps where the joint's total torque crosses zero."""
    e = c.effect
    if e.joint is None or e.location_key != "joint" or e.evidence_plot not in ("axial", "axial_branches"):
        return "a deviation along the whole contour that follows the load", []
    data = rows.dataset(model.robot, model.input_map())
    ctx = model.context(data)
    total = joint_torque(ctx.frame_wrench, e.joint) + ctx.static_torque[:, e.joint - 1]
    order = np.argsort(rows.t, kind="stable")
    arc = rows.arc_deg[order]
    tau = at_points(rows, data, total[ctx.row_reading])[order]
    if e.evidence_plot == "axial_branches":
        state = at_points(rows, data, e.loading(ctx, ctx.frame_wrench, e.theta)[ctx.row_reading])[order]
        marks = _zero_crossings(state, arc)
        turns = _angles(_reversals(tau, arc))
        what = (f"where its loading state switches after each reversal of joint {e.joint}'s torque"
                + (f" (the torque turns at {turns} deg)" if turns else ""))
    else:
        marks, what = _zero_crossings(tau, arc), f"where joint {e.joint}'s total torque crosses zero"
    return (f"a step at {_angles(marks)} deg along the contour, {what}" if marks else
            f"a step {what}, which the measured contour does not hold (its size is uncertain)"), marks


def _angles(marks: list[float]) -> str:
    return ", ".join(f"{m:.0f}" for m in sorted(m % 360 for m in marks)[:6])


def _reversals(tau: np.ndarray, arc: np.ndarray) -> list[float]:
    """Where a torque series turns back by more than REVERSAL_FRACTION of its range (its extrema)."""
    thr = REVERSAL_FRACTION * max(float(np.ptp(tau)), 1e-9)
    out, ref, direction, k_ref = [], tau[0], 0.0, 0
    for k in range(1, len(tau)):
        delta = tau[k] - ref
        if delta * direction > 0:
            ref, k_ref = tau[k], k
        elif abs(delta) > thr:
            if direction != 0:
                out.append(float(arc[k_ref]))
            direction, ref, k_ref = np.sign(delta), tau[k], k
    return out


def _zero_crossings(x: np.ndarray, arc: np.ndarray) -> list[float]:
    """Where a series changes sign between two points, interpolated linearly between them."""
    s = np.sign(x)
    k = np.nonzero(s[1:] * s[:-1] < 0)[0]
    return [float(arc[i] + (arc[i + 1] - arc[i]) * x[i] / (x[i] - x[i + 1])) for i in k]
