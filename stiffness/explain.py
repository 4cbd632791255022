"""Plain words for a diagnosis candidate: which effect, where, how large, how much it explains."""

from __future__ import annotations

import math

import numpy as np

from .effects.joint_spring import JointSpring
from .units import RAD_TO_DEG


def _axial_compliance(model, joint: int) -> float | None:
    for e in model.effects:
        if isinstance(e, JointSpring) and e.joint == joint and "rz" in e.components:
            return float(e.theta[e.components.index("rz")])
    return None


def size_text(c, model, ctx) -> str:
    """The estimated size of the candidate's effect, in the units a person reads."""
    e, est, se = c.effect, c.estimate, c.std_error
    name = e.name
    if name == "backlash":
        return (f"lost motion {est[0] * RAD_TO_DEG:.4f} deg (± {se[0] * RAD_TO_DEG:.4f}), "
                f"smoothed over ±{e.fixed_width:.0f} Nm")
    if name == "hysteresis":
        smooth = (f", moving between branches over {e.fixed_transition:.0f} Nm" if e.fixed_transition
                  else ", switching at once")
        return (f"offset {est[0] * RAD_TO_DEG:+.4f} deg (± {se[0] * RAD_TO_DEG:.4f}) by the direction the torque "
                f"last moved{smooth}")
    if name == "nonlinear_stiffness":
        c_ax = _axial_compliance(model, e.joint)
        if e.form == "cubic":
            rel = f", {100 * est[0] / c_ax:+.0f} % of the axial compliance at {e.reference_torque_Nm:.0f} Nm" \
                if c_ax else ""
            return f"cubic compliance {est[0]:.3g} rad/Nm (± {se[0]:.2g}){rel}"
        rel = f" ({100 * est[0] / c_ax:+.0f} % of the axial compliance)" if c_ax else ""
        return f"extra compliance {est[0]:.3g} rad/Nm{rel} below a knee of {e.fixed_knee:.0f} Nm"
    if name == "link_bending":
        if est[0] > 0:
            return f"bending stiffness EI = {1 / est[0]:.3g} N m² (1/EI = {est[0]:.3g} ± {se[0]:.2g})"
        return f"1/EI = {est[0]:.3g} ± {se[0]:.2g} (not a physical, positive compliance)"
    if name == "sensor_misalignment":
        ang = np.linalg.norm(est) * RAD_TO_DEG
        axis = est / max(np.linalg.norm(est), 1e-300)
        return f"sensor turned by {ang:.3f} deg about ({axis[0]:+.2f}, {axis[1]:+.2f}, {axis[2]:+.2f})"
    if name == "drift":
        v = np.linalg.norm(est[:3]) * 60e3
        w = np.linalg.norm(est[3:]) * RAD_TO_DEG * 60
        return f"drift {v:.4f} mm/min and {w:.5f} deg/min within each configuration"
    if name == "joint_6dof":
        parts = [f"{comp} {1 / val:.3g} {'N/m' if comp in 'xyz' else 'Nm/rad'}"
                 for comp, val, s in zip(e.components, est, se) if val > 3 * s]
        return "stiffness " + (", ".join(parts) if parts else "below the noise in every direction")
    return ", ".join(f"{p.key} = {v * p.yaml_factor:.4g}" for p, v in zip(e.params, est))


def describe(c, model, ctx, result) -> str:
    where = f" at {e_loc(c.effect)}" if c.effect.joint is not None else ""
    pct = 100 * c.cv_improvement
    passed = [k.replace("_", " ") for k, ok in c.criteria.items() if ok]
    verdict = "Missing" if c.named else ("Partial" if c.significant else "Not supported")
    folds = "by configuration" if len(ctx.config_labels) >= 2 else "over blocks of time (one configuration)"
    change = [f"{before:.{d}f} -> {after:.{d}f} {unit}" for before, after, d, unit in (
        (result.rms_position_mm, c.rms_position_mm_after, 4, "mm"),
        (result.rms_rotation_deg, c.rms_rotation_deg_after, 5, "deg")) if not math.isnan(before)]
    return (f"{verdict}: {c.name}{where}, {size_text(c, model, ctx)}. It explains {pct:.0f} % of the "
            f"remaining error under cross-validation {folds} (RMS {', '.join(change)}); "
            f"criteria passed: {', '.join(passed) or 'none'}.")


def e_loc(effect) -> str:
    return f"{effect.location_key} {effect.joint}"
