"""Plain words for a diagnosis candidate: which effect, where, how large, how much it explains."""

from __future__ import annotations

import math


def size_text(c, model, ctx) -> str:
    """The estimated size of the candidate's effect, in the units a person reads (the effect's own words)."""
    return c.effect.size_text(c.estimate, c.std_error, model)


def describe(c, model, ctx, result) -> str:
    where = f" at {e_loc(c.effect)}" if c.effect.joint is not None else ""
    pct = 100 * c.cv_improvement
    passed = [k.replace("_", " ") for k, ok in c.criteria.items() if ok]
    verdict = "Missing" if c.named else ("Partial" if c.significant else "Not supported")
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
