"""Backlash: lost motion in a joint's gearbox, a step in axial deflection where the torque changes sign.

Equation (joint i, twist at DH frame i-1, added to rz):

    delta_rz = (b / 2) * tanh(tau_i / tau_w)

b      lost motion, the total play crossed at zero torque (YAML: lost_motion_deg, deg)
tau_w  smoothing torque, the width of the transition (YAML: width_Nm, Nm; fitted by
       scipy.optimize.least_squares, bounded to [0.1, 1e4] Nm)
tau_i  joint i's axial torque, the external moment about its axis (Nm), unloaded geometry.

Diagnosis: tried at every joint that has none, with tau_w fixed at 0.5 %, 2 % and 6 % of the joint's
largest torque in the campaign, centred at the model's static torque and with its centre free per
configuration (`axial.with_free_centres`). Service: an `AxialTerm`, f = the equation above.

Example: far beyond the width the joint has crossed half its play, and the step is odd in tau.

>>> import numpy as np
>>> b = Backlash(joint=3, lost_motion_rad=np.radians(0.01), width_Nm=20.0)
>>> print(f"{np.degrees(b.axial_twist(1e4)):.4f} deg, {np.degrees(b.axial_twist(-1e4)):.4f} deg")
0.0050 deg, -0.0050 deg
>>> float(b.axial_twist(0.0))
0.0
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..units import RAD_TO_DEG
from .axial import AxialEffect, torque_range, with_free_centres
from .base import Param, read_location, read_values


def backlash_law(tau, p):
    """delta_rz = (b / 2) tanh(tau / tau_w), p = [b (rad), tau_w (Nm)]; tau scalar or array (Nm)."""
    return p[0] * 0.5 * np.tanh(tau / p[1])


class Backlash(AxialEffect):
    name = "backlash"
    equation = "delta_rz,i = (b/2) tanh(tau_i / tau_w)"
    default_width_Nm = 20.0
    examples = ({"effect": "backlash", "joint": 3, "lost_motion_deg": 0.01, "width_Nm": 30.0},)

    def __init__(self, joint: int, lost_motion_rad: float = 0.0, width_Nm: float = default_width_Nm,
                 fit_width: bool = True):
        params = [Param("lost_motion_deg", "deg", 1e-4, yaml_factor=RAD_TO_DEG)]
        theta = [lost_motion_rad]
        if fit_width:
            params.append(Param("width_Nm", "Nm", 10.0, nonlinear=True, bounds=(0.1, 1e4)))
            theta.append(width_Nm)
        super().__init__(params, np.array(theta), joint)
        self.fixed_width = None if fit_width else width_Nm

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> Backlash:
        joint = read_location(section, "joint", cls.joints, where)
        probe = cls(joint)
        section = {"width_Nm": cls.default_width_Nm, **section}
        theta = read_values(cls.name, section, probe.params, where, ("joint",))
        return cls(joint, theta[0], theta[1])

    def to_config(self) -> dict[str, Any]:
        out = super().to_config()
        if self.fixed_width is not None:
            out["width_Nm"] = float(f"{self.fixed_width:.6g}")
        return out

    def width(self, theta: np.ndarray) -> float:
        return self.fixed_width if self.fixed_width is not None else float(theta[1])

    law = staticmethod(backlash_law)

    def law_params(self, theta: np.ndarray) -> np.ndarray:
        return np.array([theta[0], self.width(theta)])

    @classmethod
    def candidates(cls, model, ctx) -> list[list[Backlash]]:
        out = []
        for j in cls.joints:
            if not model.has(cls.name, j):
                centred = [cls(j, 0.0, w * torque_range(ctx, j), fit_width=False) for w in (0.005, 0.02, 0.06)]
                out.append(centred + with_free_centres(model, ctx, centred))
        return out

    def size_text(self, estimate, std_error, model) -> str:
        return (f"lost motion {estimate[0] * RAD_TO_DEG:.4f} deg (± {std_error[0] * RAD_TO_DEG:.4f}), "
                f"smoothed over ±{self.width(estimate):.0f} Nm")
