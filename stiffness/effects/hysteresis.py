"""Hysteresis: an axial offset that depends on the direction the joint torque last moved.

Equation (joint i, twist at DH frame i-1, added to rz):

    delta_rz = h * s_i(t)

h      offset (YAML: offset_deg, deg); friction in the gearbox makes the deflection lag the load,
       which is h < 0 with this sign convention
s_i    the loading direction: +1 after the torque tau_i last rose, -1 after it last fell, 0 before it
       first moved. It is read from the time order of the readings within each configuration; a
       change counts when it exceeds `threshold_fraction` (YAML, default 0.02) of the largest |tau_i|
       in that configuration, so repeated readings of one load state keep their direction.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..context import Context
from ..errors import ConfigError
from ..units import RAD_TO_DEG
from .axial import axial_basis, joint_torque
from .base import Effect, Param, read_location, read_values


def loading_direction(ctx: Context, tau: np.ndarray, threshold_fraction: float) -> np.ndarray:
    """s (R,) in {-1, 0, +1}: the direction tau last moved, in time order per configuration."""
    s = np.zeros(len(tau))
    for c in range(len(ctx.config_labels)):
        idx = np.nonzero(ctx.config == c)[0]
        idx = idx[np.argsort(ctx.time[idx], kind="stable")]
        thr = threshold_fraction * max(np.abs(tau[idx]).max(initial=0.0), 1e-9)
        last_dir, ref = 0.0, tau[idx[0]] if len(idx) else 0.0
        for n in idx:
            if abs(tau[n] - ref) > thr:
                last_dir = np.sign(tau[n] - ref)
                ref = tau[n]
            elif last_dir * (tau[n] - ref) > 0:
                ref = tau[n]   # still moving the same way: follow it
            s[n] = last_dir
    return s


class Hysteresis(Effect):
    name = "hysteresis"
    equation = "delta_rz,i = h s_i(t), s_i = direction tau_i last moved"

    def __init__(self, joint: int, offset_rad: float = 0.0, threshold_fraction: float = 0.02):
        super().__init__([Param("offset_deg", "deg", 1e-4, yaml_factor=RAD_TO_DEG)], np.array([offset_rad]), joint)
        self.threshold_fraction = threshold_fraction

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> Hysteresis:
        joint = read_location(section, "joint", cls.joints, where)
        thr = section.get("threshold_fraction", 0.02)
        if not isinstance(thr, (int, float)) or not 0 < thr < 1:
            raise ConfigError(f"{where}: threshold_fraction = {thr!r} must be in (0, 1)")
        theta = read_values(cls.name, section, cls(joint).params, where, ("joint", "threshold_fraction"))
        return cls(joint, theta[0], float(thr))

    def to_config(self) -> dict[str, Any]:
        return {**super().to_config(), "threshold_fraction": self.threshold_fraction}

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        key = ("loading_direction", self.joint, self.threshold_fraction)
        if W is ctx.frame_wrench and key in ctx.cache:
            s = ctx.cache[key]
        else:
            s = loading_direction(ctx, joint_torque(W, self.joint), self.threshold_fraction)
            if W is ctx.frame_wrench:
                ctx.cache[key] = s
        return axial_basis(ctx, self.joint, [s])
