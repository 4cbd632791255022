"""Nonlinear stiffness: a joint's axial compliance that changes with its torque.

Two forms (YAML: form), each added to joint i's axial twist rz at DH frame i-1:

cubic      delta_rz = c3 * tau_i * (tau_i / tau_ref)^2
           c3: extra compliance at the reference torque (YAML: cubic_rad_per_Nm, rad/Nm);
           tau_ref (YAML: reference_torque_Nm, default 1000 Nm) is fixed, not fitted.
           c3 < 0 is a spring that stiffens with load (soft near zero).
two_slope  delta_rz = c_s * tau_k * tanh(tau_i / tau_k)
           an extra compliance c_s (YAML: soft_rad_per_Nm, rad/Nm) below the knee torque tau_k
           (YAML: knee_Nm, Nm, fitted by least squares): gearboxes are softer near zero torque.

Diagnosis: tried at every joint that has none, as the cubic and as the two-slope form with the knee
fixed at 15 %, 30 % and 60 % of the joint's largest torque in the campaign, the two-slope form also
with its centre free per configuration (`axial.with_free_centres`). Service: an `AxialTerm`.

Example: the two-slope form is the soft compliance below the knee and levels off above it.

>>> e = NonlinearStiffness(joint=1, form="two_slope", theta=[5e-8, 300.0])
>>> print(f"{e.axial_twist(10.0) / 10.0:.3g} rad/Nm near 0, {e.axial_twist(3000.0):.3g} rad at 10 knees")
5e-08 rad/Nm near 0, 1.5e-05 rad at 10 knees
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..errors import ConfigError, quote
from .axial import AxialEffect, torque_range, with_free_centres
from .base import Param, read_location, read_values
from .joint_spring import axial_compliance

FORMS = ("cubic", "two_slope")


def cubic_law(tau, p):
    """delta_rz = c3 tau (tau / tau_ref)^2, p = [c3 (rad/Nm), tau_ref (Nm)]; tau scalar or array (Nm)."""
    return p[0] * tau * (tau / p[1]) ** 2


def two_slope_law(tau, p):
    """delta_rz = c_s tau_k tanh(tau / tau_k), p = [c_s (rad/Nm), tau_k (Nm)]; tau scalar or array (Nm)."""
    return p[0] * p[1] * np.tanh(tau / p[1])


class NonlinearStiffness(AxialEffect):
    name = "nonlinear_stiffness"
    equation = "delta_rz,i = c3 tau (tau/tau_ref)^2  |  c_s tau_k tanh(tau/tau_k)"
    examples = ({"effect": "nonlinear_stiffness", "joint": 1, "form": "two_slope", "soft_rad_per_Nm": 5e-8,
                 "knee_Nm": 300.0},)

    def __init__(self, joint: int, form: str = "cubic", theta: np.ndarray | None = None,
                 reference_torque_Nm: float = 1000.0, fit_knee: bool = True):
        self.form = form
        self.law = cubic_law if form == "cubic" else two_slope_law
        self.reference_torque_Nm = reference_torque_Nm
        if form == "cubic":
            params = [Param("cubic_rad_per_Nm", "rad/Nm", 1e-7)]
        else:
            params = [Param("soft_rad_per_Nm", "rad/Nm", 1e-7)]
            if fit_knee:
                params.append(Param("knee_Nm", "Nm", 100.0, nonlinear=True, bounds=(1.0, 1e5)))
        default = np.zeros(len(params)) if form == "cubic" else np.array([0.0, 300.0][:len(params)])
        super().__init__(params, default if theta is None else np.asarray(theta, float), joint)
        self.fixed_knee = None if fit_knee else float(theta[1] if theta is not None and len(theta) > 1
                                                      else 300.0)

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> NonlinearStiffness:
        joint = read_location(section, "joint", cls.joints, where)
        form = section.get("form", "cubic")
        if form not in FORMS:
            raise ConfigError(f"{where}: form = {quote(form)} must be one of {', '.join(FORMS)}")
        ref = section.get("reference_torque_Nm", 1000.0)
        if not isinstance(ref, (int, float)) or not ref > 0:
            raise ConfigError(f"{where}: reference_torque_Nm = {quote(ref)} must be a number > 0")
        probe = cls(joint, form)
        if form == "two_slope":
            section = {"knee_Nm": 300.0, **section}
        theta = read_values(cls.name, section, probe.params, where, ("joint", "form", "reference_torque_Nm"))
        return cls(joint, form, theta, float(ref))

    def to_config(self) -> dict[str, Any]:
        out = {**super().to_config(), "form": self.form}
        if self.form == "cubic":
            out["reference_torque_Nm"] = self.reference_torque_Nm
        elif self.fixed_knee is not None:
            out["knee_Nm"] = float(f"{self.fixed_knee:.6g}")
        return out

    def knee(self, theta: np.ndarray) -> float:
        return self.fixed_knee if self.fixed_knee is not None else float(theta[1])

    def law_params(self, theta: np.ndarray) -> np.ndarray:
        if self.form == "cubic":
            return np.array([theta[0], self.reference_torque_Nm])
        return np.array([theta[0], self.knee(theta)])

    @classmethod
    def candidates(cls, model, ctx) -> list[list[NonlinearStiffness]]:
        out = []
        for j in cls.joints:
            if not model.has(cls.name, j):
                T = torque_range(ctx, j)
                slopes = [cls(j, "two_slope", np.array([0.0, k * T]), fit_knee=False) for k in (0.15, 0.3, 0.6)]
                out.append([cls(j, "cubic")] + slopes + with_free_centres(model, ctx, slopes))
        return out

    def size_text(self, estimate, std_error, model) -> str:
        c_ax = axial_compliance(model, self.joint)
        if self.form == "cubic":
            rel = (f", {100 * estimate[0] / c_ax:+.0f} % of the axial compliance at {self.reference_torque_Nm:.0f} Nm"
                   if c_ax else "")
            return f"cubic compliance {estimate[0]:.3g} rad/Nm (± {std_error[0]:.2g}){rel}"
        rel = f" ({100 * estimate[0] / c_ax:+.0f} % of the axial compliance)" if c_ax else ""
        return f"extra compliance {estimate[0]:.3g} rad/Nm{rel} below a knee of {self.knee(estimate):.0f} Nm"
