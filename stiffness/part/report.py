"""The part's pages: `stiffcomp part compare|learn|diagnose --report DIR` (verdict first, then the plots).

Figures, each against the position along the contour (deg about its centroid, in the order the tool went):

* the part (Fig. 8 of the paper): (a) the contour seen along the tool axis, its error exaggerated; (b) the
  point-to-point error beside the model's account of it: the arm's deflection, what the model predicted,
  what the correction moved, and what the model missed;
* the load: the force of the cut (base axes) and the six joint torques;
* learning: what the model misses before and after;
* the diagnosis: what the model misses, with the named effect's share and the marks where it shows.
"""

from __future__ import annotations

import numpy as np
from matplotlib.figure import Figure

from ..report.html import Report
from ..report.plots import legend_below
from .compare import PartComparison, at_points
from .contour import plane_basis

# one legend holds the forces and the joints: nine colours, none shared (matplotlib's ten, without its gray)
FORCE_COLOURS = ("tab:blue", "tab:orange", "tab:green")
JOINT_COLOURS = ("tab:red", "tab:purple", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")


def _sorted(comp: PartComparison):
    o = np.argsort(comp.rows.t, kind="stable")
    return o, comp.rows.arc_deg[o]


def part_figure(comp: PartComparison, exaggerate: float | None = None) -> Figure:
    """Fig. 8 for a measured part: the contour (error exaggerated) and the error along it, with the model's
    account: deflection, prediction, correction and what the model missed."""
    r = comp.rows
    o, arc = _sorted(comp)
    if exaggerate is None:          # the largest error shown as a tenth of the contour's size, a round factor
        size = float(np.max(np.ptp(r.point, axis=0))) * 1000.0
        raw = 0.1 * size / max(float(np.max(np.abs(r.nominal_mm))), 1e-6)
        exaggerate = float(10 ** np.floor(np.log10(raw)) * min((1, 2, 5), key=lambda m: abs(np.log(raw / (
            10 ** np.floor(np.log10(raw)) * m)))))
    fig = Figure(figsize=(13, 5.6), layout="constrained")
    ax = fig.add_subplot(1, 2, 1, aspect="equal")
    a = r.axis.mean(axis=0)
    e1, e2 = plane_basis(a / np.linalg.norm(a))
    c = r.point.mean(axis=0)
    p = (r.point - c)[o] * 1000.0
    n = r.normal[o]
    nominal = p - r.nominal_mm[o][:, None] * n            # mm
    shown = nominal + exaggerate * r.nominal_mm[o][:, None] * n
    ax.plot(nominal @ e1, nominal @ e2, "k-", lw=1.0, label="nominal contour")
    ax.plot(shown @ e1, shown @ e2, "-", color="tab:blue", lw=1.0, label=f"measured (error x{exaggerate:g})")
    ax.set_xlabel("mm, across the tool axis")
    ax.set_ylabel("mm")
    ax.set_title("a) the part, seen along the tool axis")
    bx = fig.add_subplot(1, 2, 2)
    bx.plot(arc, r.nominal_mm[o], color="tab:blue", lw=1.2, label=f"part error (mean |error| {np.mean(np.abs(r.nominal_mm)):.4f} mm)")
    bx.plot(arc, r.deviation_mm[o], color="tab:red", lw=0.9, label="the arm's deflection along the normal")
    bx.plot(arc, comp.model_mm[o], color="tab:orange", lw=0.9, ls="--", label=f"{comp.model.name}: predicted deflection")
    bx.plot(arc, -r.correction_mm[o], color="tab:green", lw=0.9, ls=":", label="the correction sent (its move, negated)")
    bx.plot(arc, comp.missed_mm[o], color="k", lw=0.8, label="what the model misses")
    bx.axhline(0.0, color="k", lw=0.5)
    bx.set_xlabel("position along the contour, deg")
    bx.set_ylabel("along the surface normal, mm")
    bx.set_title("b) point-to-point error and the model's account of it")
    bx.grid(alpha=0.3)
    legend_below(fig, ax, bx, ncols=3)
    return fig


def load_figure(comp: PartComparison) -> Figure:
    """The force of the cut and the joint torques along the contour."""
    o, arc = _sorted(comp)
    fig = Figure(figsize=(13, 4.8), layout="constrained")
    ax = fig.add_subplot(1, 2, 1)
    for k, lab in enumerate(("Fx", "Fy", "Fz")):
        ax.plot(arc, comp.rows.wrench_base[o, k], lw=1.0, color=FORCE_COLOURS[k], label=lab)
    ax.set_xlabel("position along the contour, deg")
    ax.set_ylabel("force, N (base axes)")
    ax.set_title("the cut's force")
    ax.grid(alpha=0.3)
    bx = fig.add_subplot(1, 2, 2)
    for j in range(6):
        bx.plot(arc, comp.torque[o, j], lw=1.0, color=JOINT_COLOURS[j], label=f"joint {j + 1}")
    bx.set_xlabel("position along the contour, deg")
    bx.set_ylabel("external joint torque, Nm")
    bx.set_title("the joints' torques")
    bx.grid(alpha=0.3)
    legend_below(fig, ax, bx, ncols=9)
    return fig


def learn_figure(learned) -> Figure:
    """What the model misses along each part's contour, before and after learning (`learn.Learned`): the
    residuals the learning's text counts, so the legend's RMS is the text's (over the points the fit kept)."""
    parts, data, fit = learned.parts, learned.data, learned.fit
    fig = Figure(figsize=(12, 3.6 * len(parts)), layout="constrained")
    axes = []
    for k, rows in enumerate(parts):
        mine = np.asarray(data.config) == rows.label
        sub = _subset(data, mine)
        kept = at_points(rows, sub, ~fit.outlier[mine]).astype(bool)
        ax = fig.add_subplot(len(parts), 1, k + 1)
        o = np.argsort(rows.t, kind="stable")
        arc = rows.arc_deg[o]
        for values, colour, when in ((learned.missed_before[mine], "tab:red", "before"),
                                     (fit.residual[mine, 0], "tab:blue", "after")):
            at = at_points(rows, sub, values)
            ax.plot(arc, at[o], color=colour, lw=0.9,
                    label=f"{when}: RMS {np.sqrt(np.mean(at[kept] ** 2)):.4f} mm over the {int(kept.sum())} points kept")
        ax.axhline(0.0, color="k", lw=0.5)
        ax.set_title(f"{rows.label}: what the model misses ({rows.part.source})")
        ax.set_ylabel("mm")
        ax.grid(alpha=0.3)
        ax.legend(loc="upper right")
        axes.append(ax)
    axes[-1].set_xlabel("position along the contour, deg")
    return fig


def diagnosis_figure(comp: PartComparison, contribution: np.ndarray, label: str, marks: list[float]) -> Figure:
    """What the model misses along the contour, the named effect's share of it, and where it shows."""
    o, arc = _sorted(comp)
    fig = Figure(figsize=(12, 4.4), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(arc, comp.missed_mm[o], ".", ms=3, color="tab:gray", label="what the model misses")
    ax.plot(arc, contribution[o], color="tab:red", lw=1.2, label=f"{label}: its share")
    for m in marks:
        ax.axvline(m, color="tab:red", lw=0.6, ls=":")
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xlabel("position along the contour, deg (dotted: where the effect shows)")
    ax.set_ylabel("along the surface normal, mm")
    ax.grid(alpha=0.3)
    ax.legend(loc="upper right")
    return fig


def compare_report(comp: PartComparison, command: str) -> Report:
    s = comp.summary()
    rep = Report("stiffcomp part compare", f"{comp.rows.part.source} against {comp.rows.trace.source}")
    rep.verdict("\n".join(comp.lines()[1:]), "info")
    rep.figure(part_figure(comp), "part", "The part: its error along the contour beside the model's account of it")
    rep.figure(load_figure(comp), "load", "The force of the cut and the joints' torques along the contour")
    rep.table(["figure", "mm"], [[k, v] for k, v in s.items() if k.endswith("_mm")])
    rep.preformatted(command)
    return rep


def learn_report(learned, command: str) -> Report:
    rep = Report("stiffcomp part learn", ", ".join(p.part.source for p in learned.parts))
    rep.verdict("\n".join(learned.lines()), "bad" if learned.problems else "info")
    rep.figure(learn_figure(learned), "learned", "What the model misses of each part, before and after")
    rep.preformatted(command)
    return rep


def diagnose_report(message: str, verdict_kind: str, comp: PartComparison, pd, command: str) -> Report:
    rep = Report("stiffcomp part diagnose", f"{comp.rows.part.source} against {comp.rows.trace.source}")
    rep.verdict(message, verdict_kind)
    best = pd.diagnosis.best
    if best is not None:
        data = pd.data
        first = data.config == comp.rows.label
        contrib = at_points(comp.rows, _subset(data, first), best.contribution[first][:, 0])
        rep.figure(diagnosis_figure(comp, contrib, best.effect.label, pd.marks_deg or []), "evidence",
                   "What the model misses along the contour, and the named effect's share")
    rep.figure(part_figure(comp), "part", "The part and the model's account of it")
    rep.table(["effect", "where", "CV %", "dBIC", "named"],
              [[c.name, c.where, 100 * c.cv_improvement, c.delta_bic, c.named] for c in pd.diagnosis.candidates[:10]])
    rep.preformatted(command)
    return rep


def _subset(data, mask):
    return data.subset(np.nonzero(mask)[0])
