"""Drift: a slow deflection offset that grows with time within a configuration (thermal).

Equation: a rigid twist of the whole arm about the base origin, growing linearly from the first
reading of each configuration (where the unloaded reference was taken):

    delta_base = [v, w] * (t - t0_config)

v   translational rate in base axes (YAML: x_mm_per_min, y_mm_per_min, z_mm_per_min)
w   rotational rate in base axes (YAML: rx_deg_per_min, ry_deg_per_min, rz_deg_per_min)
A body at p drifts by v t + (w t) x p and turns by w t. Applied at spring site 0 (the base frame).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..context import Context
from ..units import M_TO_MM, RAD_TO_DEG
from .base import Effect, Param, read_values

M_PER_S_TO_MM_PER_MIN = M_TO_MM * 60.0
RAD_PER_S_TO_DEG_PER_MIN = RAD_TO_DEG * 60.0


class Drift(Effect):
    name = "drift"
    per_joint = False
    joints = ()
    equation = "delta_base = [v, w] (t - t0_config)"

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
