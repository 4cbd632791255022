"""Gravity compensation of the sensor wrench (the real-time part; `stiffness.payload` identifies the payload).

A static payload of mass m with centre of gravity c (sensor frame) loads the sensor with

    F_g = m R_s^T g,     T_g = c x F_g                                   (sensor axes, about its origin)

with R_s the sensor's orientation in the base and g the gravity vector in base axes (m/s^2). The
sensor reads W = W_ext + [F_g; T_g] + b, with b its bias, so the external wrench is

    W_ext = W - b - [F_g; T_g].

The bodies (sensor, tool, fixture, workpiece) combine into one mass and one centre of gravity. Tare
adds the current external wrench to the bias, so the load at that moment reads zero.

The offline identification of m, c and b from static poses is `stiffness.payload`.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from stiffness.yamlio import Strict

# the bodies the sensor carries (the robot's frames are `stiffness.robot.BODIES`)
PAYLOAD_BODIES = ("sensor", "tool", "fixture", "workpiece")


class BodyConfig(Strict):
    """One body the sensor carries: its mass and its centre of gravity in the sensor frame."""

    mass_kg: float = Field(0.0, ge=0.0, le=1000.0)
    cog_mm: list[float] = Field(default_factory=lambda: [0.0, 0.0, 0.0], min_length=3, max_length=3)


class GravityConfig(Strict):
    """``gravity``: the gravity vector in base axes, the bodies the sensor carries, the sensor's bias."""

    g_mps2: list[float] = Field(default_factory=lambda: [0.0, 0.0, -9.81], min_length=3, max_length=3)
    sensor: BodyConfig = Field(default_factory=BodyConfig)
    tool: BodyConfig = Field(default_factory=BodyConfig)
    fixture: BodyConfig = Field(default_factory=BodyConfig)
    workpiece: BodyConfig = Field(default_factory=BodyConfig)
    bias: list[float] = Field(default_factory=lambda: [0.0] * 6, min_length=6, max_length=6)


class GravityCompensator:
    """Remove payload weight and bias from sensor wrenches.

    Parameters
    ----------
    mass_kg : float
        Total mass of everything the sensor carries.
    cog_m : (3,) centre of gravity in the sensor frame, m
    bias : (6,) sensor bias [N, N, N, Nm, Nm, Nm]
    g : (3,) gravity in base axes, m/s^2
    """

    def __init__(self, mass_kg: float, cog_m: np.ndarray, bias: np.ndarray, g: np.ndarray):
        self.mass = float(mass_kg)
        self.cog = np.asarray(cog_m, dtype=float)
        self.bias = np.asarray(bias, dtype=float).copy()
        self.g = np.asarray(g, dtype=float)
        self._mg = (self.mass * self.g).tolist()

    @classmethod
    def from_config(cls, section: GravityConfig) -> GravityCompensator:
        masses = np.array([getattr(section, b).mass_kg for b in PAYLOAD_BODIES])
        cogs = np.array([getattr(section, b).cog_mm for b in PAYLOAD_BODIES]) / 1000.0
        m = masses.sum()
        cog = (masses[:, None] * cogs).sum(0) / m if m > 0 else np.zeros(3)
        return cls(m, cog, np.array(section.bias), np.array(section.g_mps2))

    def payload_wrench(self, R_sensor) -> list[float]:
        """[F_g; T_g] in sensor axes for the sensor orientation ``R_sensor`` (3x3, base; array or lists)."""
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = (
            R_sensor.tolist() if isinstance(R_sensor, np.ndarray) else R_sensor)
        gx, gy, gz = self._mg
        fx = r00 * gx + r10 * gy + r20 * gz               # R^T (m g)
        fy = r01 * gx + r11 * gy + r21 * gz
        fz = r02 * gx + r12 * gy + r22 * gz
        cx, cy, cz = self._cog
        return [fx, fy, fz, cy * fz - cz * fy, cz * fx - cx * fz, cx * fy - cy * fx]

    def compensate(self, wrench, R_sensor) -> list[float]:
        """The external wrench (sensor axes, six floats) from a reading."""
        return [w - b - g for w, b, g in zip(wrench, self._bias, self.payload_wrench(R_sensor))]

    def tare(self, wrench, R_sensor) -> None:
        """Take the current external wrench as the new zero (adds it to the bias)."""
        self.bias = self.bias + np.array(self.compensate(wrench, R_sensor))

    @property
    def bias(self) -> np.ndarray:
        return np.array(self._bias)

    @bias.setter
    def bias(self, value) -> None:
        self._bias = [float(v) for v in value]

    @property
    def cog(self) -> np.ndarray:
        return np.array(self._cog)

    @cog.setter
    def cog(self, value) -> None:
        self._cog = [float(v) for v in value]
