"""Plain words for a diagnosis: each candidate (which effect, where, how large, how much it explains) and the
verdict over them all."""

from __future__ import annotations

import math

import numpy as np


def size_text(c, model, ctx) -> str:
    """The estimated size of the candidate's effect, in the units a person reads (the effect's own words)."""
    return c.effect.size_text(c.estimate, c.std_error, model)


def describe(c, model, ctx, result) -> str:
    where = f" at {e_loc(c.effect)}" if c.effect.joint is not None else ""
    pct = 100 * c.cv_improvement
    passed = [k.replace("_", " ") for k, ok in c.criteria.items() if ok]
    verdict = ("Missing" if c.named else "Not physical" if c.significant and not c.physical else
               "Partial" if c.significant else "Not supported")
    folds = "by configuration" if len(ctx.config_labels) >= 2 else "over blocks of time (one configuration)"
    change = [f"{before:.{d}f} -> {after:.{d}f} {unit}" for before, after, d, unit in (
        (result.rms_position_mm, c.rms_position_mm_after, 4, "mm"),
        (result.rms_rotation_deg, c.rms_rotation_deg_after, 5, "deg")) if not math.isnan(before)]
    centre = getattr(c.effect, "centre_text", lambda m, x: "")(model, ctx)
    return (f"{verdict}: {c.name}{where}{centre}, {size_text(c, model, ctx)}. It explains {pct:.0f} % of the "
            f"remaining error under cross-validation {folds} (RMS {', '.join(change)}); "
            f"criteria passed: {', '.join(passed) or 'none'}.")


def e_loc(effect) -> str:
    return f"{effect.location_key} {effect.joint}"


def nanmax(*values: float) -> float:
    """The largest of the values that are not NaN (a kind not measured gives NaN); NaN if none."""
    v = [x for x in values if not np.isnan(x)]
    return float(max(v)) if v else float("nan")


def verdict_of(candidates: list, lof: dict, result) -> tuple[str, str]:
    """The verdict (missing_effect, unexplained, no_missing_effect) and its message, from the candidates ranked
    named first (`discovery.Candidate`), the lack of fit ``lof`` and the base fit ``result``."""
    structure_left = lof["worst_body"] > lof["threshold"]
    best = candidates[0] if candidates and candidates[0].named else None
    if best is not None:
        ref = lof["position"] / max(result.rms_position_mm, 1e-300)   # 1 / noise, per mm
        left = best.rms_position_mm_after * ref
        left_rot = best.rms_rotation_deg_after * lof["rotation"] / max(result.rms_rotation_deg, 1e-300)
        if nanmax(left, left_rot) > lof["threshold"]:
            left_text = " / ".join(f"{x:.2f}x" for x in (left, left_rot) if not np.isnan(x))
            return "missing_effect", (best.explanation + f" Structure remains after it ({left_text} the noise): "
                                      "add it, fit, and diagnose again.")
        return "missing_effect", best.explanation
    unphysical = [c for c in candidates if c.significant and not c.physical]
    against = (f" {unphysical[0].name} passes the tests only with a negative compliance, which no robot has: a sign "
               "of data read wrong (a radius, a frame), not of an effect.") if unphysical else ""
    if structure_left:
        nibblers = [c for c in candidates if c.significant and c.physical]
        also = (f" ({nibblers[0].name} passes the tests but removes only {100 * nibblers[0].excess_explained:.0f} %"
                " of the excess)") if nibblers else ""
        return "unexplained", (
            f"The residual ({result.rms_text()}; worst body "
            f"{lof['worst_body']:.2f}x the noise of {lof['reference']}) holds structure that no effect in the "
            f"library explains{also}. See the residual patterns; the diagnosis does not guess.{against}")
    return "no_missing_effect", (
        f"The residual ({result.rms_text()}) is at the noise of {lof['reference']} ("
        + ", ".join(f"{lof[k]:.2f}x" for k in ("position", "rotation") if not np.isnan(lof[k]))
        + ") and no library effect "
        "improves the model by more than one criterion: nothing is missing." + against)
