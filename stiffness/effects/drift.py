"""Drift: a slow deflection offset that grows with time within a configuration (thermal).

Equation: a rigid twist of the whole arm about the base origin, growing linearly from the first
reading of each configuration (where the unloaded reference was taken):

    delta_base = [v, w] * (t - t0_config)

v   translational rate in base axes (YAML: x_mm_per_min, y_mm_per_min, z_mm_per_min)
w   rotational rate in base axes (YAML: rx_deg_per_min, ry_deg_per_min, rz_deg_per_min)
A body at p drifts by v t + (w t) x p and turns by w t. Applied at spring site 0 (the base frame).

Diagnosis: tried once when the model lacks it. Service: `Ignored`, with `SERVICE_REASON` logged once.

Example: a rate read from YAML units and written back; the service leaves it out.

>>> d = Drift.from_config({"effect": "drift", "x_mm_per_min": 0.01}, None, "example")
>>> print(f"{d.theta[0]:.3g} m/s", d.to_config()["x_mm_per_min"], "mm/min")
1.67e-07 m/s 0.01 mm/min
>>> [type(t).__name__ for t in d.realtime(robot=None)]
['Ignored']
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..data.campaign import Context
from ..units import M_TO_MM, RAD_TO_DEG
from .base import Effect, Param, read_values
from .terms import Ignored

M_PER_S_TO_MM_PER_MIN = M_TO_MM * 60.0
RAD_PER_S_TO_DEG_PER_MIN = RAD_TO_DEG * 60.0
# Why the service leaves drift out: the campaign's drift is measured from each configuration's unloaded
# reference time, which the service does not have, and its tare resets what drift would measure from;
# extrapolating a campaign's drift rate over hours of machining would send a correction that grows
# without bound.
SERVICE_REASON = ("drift is how a campaign's readings wandered over time (thermal), not a deflection under load "
                  "(docs/service.md)")


class Drift(Effect):
    name = "drift"
    per_joint = False
    joints = ()
    equation = "delta_base = [v, w] (t - t0_config)"
    examples = ({"effect": "drift", "x_mm_per_min": 0.01},)

    def __init__(self, theta: np.ndarray | None = None):
        params = [Param(f"{a}_mm_per_min", "mm/min", 1e-7, M_PER_S_TO_MM_PER_MIN) for a in "xyz"]
        params += [Param(f"{a}_deg_per_min", "deg/min", 1e-8, RAD_PER_S_TO_DEG_PER_MIN) for a in ("rx", "ry", "rz")]
        super().__init__(params, np.zeros(6) if theta is None else theta, None)

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> Drift:
        return cls(read_values(cls.name, section, cls().params, where))

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        B = self.zeros(ctx, 6)
        for k in range(6):
            B[:, k, 0, k] = ctx.t_rel
        return B

    def realtime(self, robot) -> list[Ignored]:
        return [Ignored(self.label, SERVICE_REASON)]

    @classmethod
    def candidates(cls, model, ctx) -> list[list[Drift]]:
        return [] if model.has(cls.name) else [[cls()]]

    def size_text(self, estimate, std_error, model) -> str:
        v = np.linalg.norm(estimate[:3]) * M_PER_S_TO_MM_PER_MIN
        w = np.linalg.norm(estimate[3:]) * RAD_PER_S_TO_DEG_PER_MIN
        return f"drift {v:.4f} mm/min and {w:.5f} deg/min within each configuration"
