"""The diagnosis as an HTML page (verdict first) and as JSON."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..data.residuals import patterns
from ..kinematics.robot import BODIES
from ..report.html import Report
from .discovery import Diagnosis
from .plots import axial_residual_vs_torque, evidence, residual_vs_force, residual_vs_time

VERDICT_KIND = {"missing_effect": "warn", "no_missing_effect": "good", "unexplained": "bad"}


def to_dict(d: Diagnosis, top: int | None = None) -> dict[str, Any]:
    cands = d.candidates if top is None else d.candidates[:top]
    return {
        "verdict": d.verdict,
        "message": d.message,
        "rms_position_mm": d.fit.rms_position_mm,
        "rms_rotation_deg": d.fit.rms_rotation_deg,
        "noise": d.noise,
        "lack_of_fit": d.lack_of_fit,
        "outliers": d.fit.outliers(),
        "unidentifiable": d.fit.unidentifiable,
        "worst": {k: d.worst[k] for k in ("body", "component", "config", "load_range")},
        "candidates": [{
            "effect": c.name,
            "joint": c.joint,
            "rms_position_mm_after": c.rms_position_mm_after,
            "rms_rotation_deg_after": c.rms_rotation_deg_after,
            "cv_improvement": c.cv_improvement,
            "delta_bic": c.delta_bic,
            "p_value": c.p_value,
            "criteria": c.criteria,
            "significant": c.named,
            "passes_tests": c.significant,
            "excess_explained": c.excess_explained,
            "explanation": c.explanation,
            "entry": {**c.entry(), **c.add_options()},     # every option its text advises, for a script
        } for c in cands],
    }


def build_report(d: Diagnosis, model_path: str, data_path: str, plots: bool = True) -> Report:
    rep = Report("stiffcomp diagnose", f"model {model_path}, data {data_path} ({len(d.ctx.data)} rows)")
    rep.verdict(f"{d.verdict}: {d.message}", VERDICT_KIND[d.verdict])
    best = d.best
    if best is not None:
        loc = f" --{best.effect.location_key} {best.joint}" if best.joint is not None else ""
        rep.heading("Next step")
        rep.paragraph("Add the named effect, fit, and compare before and after:")
        rep.preformatted(f"stiffcomp model add {model_path} {best.name}{loc} -o with_{best.name}.yaml\n"
                         f"stiffcomp fit with_{best.name}.yaml {data_path} -o with_{best.name}_fitted.yaml\n"
                         f"stiffcomp compare {model_path} with_{best.name}_fitted.yaml {data_path} --report compare")
    rep.heading("Fit of the model as it is")
    noise = d.noise or {}
    rep.table(["", "residual RMS", "noise (repeated readings)", "ratio"], [
        ["position (mm)", d.fit.rms_position_mm, noise.get("position_mm"), d.lack_of_fit["position"]],
        ["rotation (deg)", d.fit.rms_rotation_deg, noise.get("rotation_deg"), d.lack_of_fit["rotation"]],
    ], caption="RMS per component; the ratio is against " + d.lack_of_fit["reference"])
    _outliers(rep, d)
    rep.heading("Where the model fails")
    w = d.worst
    rep.paragraph(f"Worst body {w['body']}, component {w['component']}, configuration {w['config']}, "
                  f"load range {w['load_range']} (RMS in units of the noise of {d.lack_of_fit['reference']}: "
                  f"{d.lack_of_fit['position_mm']:.3g} mm, {d.lack_of_fit['rotation_deg']:.3g} deg; 1 is noise).")
    for key, title in (("body", "body"), ("component", "component"), ("config", "configuration"),
                       ("load_range", "load range (|F|)")):
        sc = w["scores"][key]
        rep.table([title] + list(sc), [["RMS / noise"] + list(sc.values())], fmt="{:.2f}")
    rep.heading("Candidate effects, best first")
    rep.table(["effect", "where", "CV improvement", "ΔBIC", "F-test p", "RMS after (mm)", "RMS after (deg)",
               "counts"],
              [[c.name, c.where, c.cv_improvement, c.delta_bic, c.p_value, c.rms_position_mm_after,
                c.rms_rotation_deg_after, "yes" if c.named else "no"] for c in d.candidates],
              caption="An effect counts when it passes cross-validation by configuration (CV improvement "
                      ">= 0.5 %) and at least one of: ΔBIC < -10, F-test p below 1 % / number of candidates.")
    for c in d.candidates[:3]:
        rep.paragraph(c.explanation)
    if plots:
        resid, sigma = d.fit.residual, d.fit.sigma
        if best is not None:
            rep.figure(evidence(best, d.ctx, resid, sigma), "evidence",
                       f"Evidence for {best.name}: the residual before it is added, and what it explains.")
        rep.figure(axial_residual_vs_torque(d.ctx, resid, sigma, best.joint if best and
                                            best.effect.location_key == "joint" else None),
                   "axial_residual_vs_torque", "The residual as each joint's unexplained axial rotation.")
        rep.figure(residual_vs_time(d.ctx, resid), "residual_vs_time", "Residual against time.")
        rep.figure(residual_vs_force(d.ctx, resid), "residual_vs_force", "Residual against the sensor force.")
    pats = patterns(d.ctx, d.fit.residual, d.fit.sigma)[:8]
    rep.heading("Residual patterns")
    rep.paragraph("How much of the residual simple physical quantities explain (R²). They point at a "
                  "pattern; they are not effects.")
    rep.table(["pattern", "R²"], [[p["pattern"], p["r2"]] for p in pats], fmt="{:.3f}")
    return rep


def _outliers(rep: Report, d: Diagnosis) -> None:
    """The rows left out as gross errors, by file line, with the size of their residual."""
    rep.heading("Gross errors")
    rows = d.fit.outlier.nonzero()[0]
    if not len(rows):
        rep.paragraph("No row was judged a gross error (robust fit; see docs/measurement_format.md).")
        return
    r = d.fit.residual[rows]
    rep.paragraph(d.fit.outlier_text() + ". They are left out of the fit and of every candidate's evidence; "
                  "a gross error does not repeat across the readings of one load state, a missing effect does.")
    rep.table(["line", "configuration", "body", "|position residual| (mm)", "|rotation residual| (deg)"],
              [[int(d.ctx.data.line[i]), d.ctx.data.config[i], BODIES[d.ctx.data.body[i]],
                float(np.linalg.norm(np.nan_to_num(e[:3]))), float(np.linalg.norm(np.nan_to_num(e[3:])))]
               for i, e in zip(rows[:200], r[:200])], caption="At most 200 rows are listed.")
