"""The HIL's true payload: the weight the virtual sensor carries, from the scenario's ``payload`` section.

Written apart from the service's `service.gravity.GravityCompensator` on purpose: the truth of a HIL
run shares neither the code nor the config it checks, so a wrong ``gravity`` section in the service
config, or a wrong gravity compensation, shows in the HIL as a wrench the PLC reads and a path error.

Each body i (mass m_i, centre of gravity c_i in sensor axes) hangs its own weight on the sensor, with
R_s the sensor's orientation in the base and g the gravity vector in base axes:

    F_i = m_i R_s^T g,    T_i = c_i x F_i        (sensor axes, moments about the sensor origin)

The sensor reads the sum over the bodies, sum_i [F_i; T_i], plus its bias b.

The arm carries the same bodies: their weight is part of the truth's static joint torque tau_s
(`hil.robot_stub.RobotStub`), as one mass m = sum_i m_i at the centre c = sum_i m_i c_i / m.
"""

from __future__ import annotations

import numpy as np

from service.gravity import PAYLOAD_BODIES  # the keys only: the physics below is the HIL's own
from stiffness.kinematics.statics import PayloadConfig


class TruePayload:
    """The payload's weight wrench on the sensor, body by body.

    Parameters
    ----------
    section : a payload section (the scenario's ``payload``; the same keys as the service config's
        ``gravity``): ``g_mps2`` (3,) m/s^2 in base axes, per body ``mass_kg`` and ``cog_mm`` (sensor
        frame, mm), and ``bias`` (6,) N and Nm.
    """

    def __init__(self, section):
        bodies = [getattr(section, b) for b in PAYLOAD_BODIES]
        self.masses = np.array([b.mass_kg for b in bodies], dtype=float)          # (n,) kg
        self.cogs = np.array([b.cog_mm for b in bodies], dtype=float) / 1000.0   # (n, 3) m
        self.g = np.asarray(section.g_mps2, dtype=float)
        self.bias = np.asarray(section.bias, dtype=float)

    def wrench(self, R_s: np.ndarray) -> np.ndarray:
        """sum_i [F_i; T_i], (6,) in N and Nm, sensor axes, for the sensor orientation ``R_s`` (3x3, base)."""
        F = np.outer(self.masses, np.asarray(R_s).T @ self.g)                    # (n, 3) each body's weight
        return np.concatenate([F.sum(0), np.cross(self.cogs, F).sum(0)])

    def carried(self) -> PayloadConfig:
        """The bodies as one mass (kg) at their common centre of gravity (sensor frame, mm): what the
        arm carries beyond the sensor, for the truth's static torque."""
        m = float(self.masses.sum())
        c = self.masses @ self.cogs / m if m > 0 else np.zeros(3)
        return PayloadConfig(mass_kg=m, cog_mm=(1000.0 * c).tolist())
