"""Sensor misalignment: the F/T sensor is turned by a small rotation against its assumed frame.

Equation (an input effect: it corrects the measured wrench before it is transported, Eq. 4):

    F_true = R(phi) F_measured,   T_true = R(phi) T_measured

phi    rotation vector from the measured to the assumed sensor axes (YAML: rx_deg, ry_deg, rz_deg).
The deflection is bilinear in phi and the springs, so phi is fitted by scipy.optimize.least_squares.

Diagnosis: tried once when the model lacks it. Service: an input effect (`InputTerm`), folded into
the sensor's rotation with every other input effect.

Example: a sensor turned by 90 deg about z reads a force along its x axis that is really along y.

>>> import numpy as np
>>> e = SensorMisalignment(np.radians([0.0, 0.0, 90.0]))
>>> np.round(e.wrench(None, e.theta, np.array([[100.0, 0, 0, 0, 0, 0]])), 6).tolist()
[[0.0, 100.0, 0.0, 0.0, 0.0, 0.0]]
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..data.campaign import Context
from ..kinematics.spatial import exp_so3
from ..units import RAD_TO_DEG
from .base import Effect, Param, read_values


class SensorMisalignment(Effect):
    name = "sensor_misalignment"
    kind = "input"
    per_joint = False
    joints = ()
    equation = "W_true = blockdiag(R(phi), R(phi)) W_measured"
    examples = ({"effect": "sensor_misalignment", "rz_deg": 3.0},)

    def __init__(self, phi_rad: np.ndarray | None = None):
        params = [Param(f"{a}_deg", "deg", 1e-2, yaml_factor=RAD_TO_DEG, nonlinear=True, bounds=(-0.5, 0.5))
                  for a in ("rx", "ry", "rz")]
        super().__init__(params, np.zeros(3) if phi_rad is None else phi_rad, None)

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> SensorMisalignment:
        return cls(read_values(cls.name, section, cls().params, where))

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        return np.zeros((ctx.n_readings, 0, 12, 6))   # no twist of its own: it acts on the wrench

    def wrench(self, ctx: Context, theta: np.ndarray, wrench_sensor: np.ndarray) -> np.ndarray:
        R = exp_so3(theta)
        return np.concatenate([wrench_sensor[:, :3] @ R.T, wrench_sensor[:, 3:] @ R.T], axis=1)

    @classmethod
    def candidates(cls, model, ctx) -> list[list[SensorMisalignment]]:
        return [] if model.has(cls.name) else [[cls()]]

    def size_text(self, estimate, std_error, model) -> str:
        ang = np.linalg.norm(estimate) * RAD_TO_DEG
        axis = estimate / max(np.linalg.norm(estimate), 1e-300)
        return f"sensor turned by {ang:.3f} deg about ({axis[0]:+.2f}, {axis[1]:+.2f}, {axis[2]:+.2f})"
