"""Gravity compensation of the sensor wrench (the real-time part; `stiffness.kinematics.payload_identification` identifies the payload).

A static payload of mass m with centre of gravity c (sensor frame) loads the sensor with

    F_g = m R_s^T g,     T_g = c x F_g                                   (sensor axes, about its origin)

with R_s the sensor's orientation in the base and g the gravity vector in base axes (m/s^2). The
sensor reads W = W_ext + [F_g; T_g] + b, with b its bias, so the external wrench is

    W_ext = W - b - [F_g; T_g].

The bodies (sensor, tool, fixture, workpiece) combine into one mass and one centre of gravity. Tare
adds the current external wrench to the bias, so the load at that moment reads zero.

Payload table. ``gravity.payloads`` holds numbered payload sets (`PayloadEntry`: name, mass, centre of
gravity, bias, optionally a TCP) that the PLC selects by ``payload_index``; index 0 is the section's own
bodies and bias. `GravityConfig.payload_sets` gives every set as a `PayloadSet`, whose [F_g; T_g] is
linear in m and m c: F_g = m R_s^T g, T_g = (m c) x (R_s^T g). Blending m, m c and b between two sets
therefore blends the gravity term exactly (`service.payloads` ramps a switch that way). A tare's
offset belongs to the sensor (its drift), not to a set: it stays across a switch.

The offline identification of m, c and b from static poses is `stiffness.kinematics.payload_identification`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from pydantic import Field, field_validator

from stiffness.files.yaml_schema import Strict, items_by_key

# the bodies the sensor carries (the robot's frames are `stiffness.kinematics.robot.BODIES`)
PAYLOAD_BODIES = ("sensor", "tool", "fixture", "workpiece")


class BodyConfig(Strict):
    """One body the sensor carries: its mass and its centre of gravity in the sensor frame."""

    mass_kg: float = Field(0.0, ge=0.0, le=1000.0)
    cog_mm: list[float] = Field(default_factory=lambda: [0.0, 0.0, 0.0], min_length=3, max_length=3)


class PayloadEntry(Strict):
    """One set of ``gravity.payloads``: what the sensor carries with one tool (or one part), as
    `stiffcomp payload` identifies it. ``tcp_mm`` (flange frame, mm) is recorded for the PLC programmer
    and the logs only: the joint correction does not depend on it (docs/config.md, "Payload table")."""

    index: int = Field(ge=1, le=0xFFFF)
    name: str = Field(min_length=1, max_length=80)
    mass_kg: float = Field(ge=0.0, le=1000.0)
    cog_mm: list[float] = Field(min_length=3, max_length=3)
    bias: list[float] = Field(default_factory=lambda: [0.0] * 6, min_length=6, max_length=6)
    tcp_mm: list[float] | None = Field(None, min_length=3, max_length=3)


class PayloadSet(NamedTuple):
    """A selectable payload in the form the cycle blends: mass (kg), m c (kg m, sensor frame), bias (N, Nm)."""

    index: int
    name: str
    mass_kg: float
    mc: tuple[float, float, float]
    bias: tuple[float, ...]
    tcp_mm: tuple[float, float, float] | None

    @property
    def cog_mm(self) -> list[float]:
        """The centre of gravity, mm (zero for no mass)."""
        return [1000.0 * v / self.mass_kg if self.mass_kg > 0 else 0.0 for v in self.mc]


class GravityConfig(Strict):
    """``gravity``: the gravity vector in base axes, the bodies the sensor carries, the sensor's bias."""

    g_mps2: list[float] = Field(default_factory=lambda: [0.0, 0.0, -9.81], min_length=3, max_length=3)
    sensor: BodyConfig = Field(default_factory=BodyConfig)
    tool: BodyConfig = Field(default_factory=BodyConfig)
    fixture: BodyConfig = Field(default_factory=BodyConfig)
    workpiece: BodyConfig = Field(default_factory=BodyConfig)
    bias: list[float] = Field(default_factory=lambda: [0.0] * 6, min_length=6, max_length=6)
    payloads: list[PayloadEntry] = Field(default_factory=list, json_schema_extra=items_by_key("index"))
    switch_ramp_s: float = Field(1.0, ge=0.0, le=60.0)

    @field_validator("payloads")
    @classmethod
    def _distinct(cls, entries: list[PayloadEntry]) -> list[PayloadEntry]:
        seen: dict[int, int] = {}
        for k, e in enumerate(entries):
            if e.index in seen:
                raise ValueError(f"index {e.index} is used twice (entries {seen[e.index] + 1} and {k + 1} of the table); "
                                 "each set needs its own number")
            seen[e.index] = k
        return entries

    def payload_sets(self) -> dict[int, PayloadSet]:
        """Every set the PLC may select, by index: 0 the section's bodies and bias, then ``payloads``."""
        masses = np.array([getattr(self, b).mass_kg for b in PAYLOAD_BODIES])
        cogs = np.array([getattr(self, b).cog_mm for b in PAYLOAD_BODIES]) / 1000.0
        sets = {0: PayloadSet(0, "gravity bodies", float(masses.sum()), tuple((masses[:, None] * cogs).sum(0).tolist()),
                              tuple(self.bias), None)}
        for e in self.payloads:
            sets[e.index] = PayloadSet(e.index, e.name, e.mass_kg, tuple(e.mass_kg * c / 1000.0 for c in e.cog_mm),
                                       tuple(e.bias), None if e.tcp_mm is None else tuple(e.tcp_mm))
        return sets


class GravityCompensator:
    """Remove payload weight and bias from sensor wrenches.

    Parameters
    ----------
    mass_kg : float
        Total mass of everything the sensor carries.
    cog_m : (3,) centre of gravity in the sensor frame, m
    bias : (6,) sensor bias [N, N, N, Nm, Nm, Nm]
    g : (3,) gravity in base axes, m/s^2

    The bias in use is the payload set's bias plus the tare's offset (`tare`); `carry` changes the
    payload and its set's bias and keeps the offset.
    """

    def __init__(self, mass_kg: float, cog_m: np.ndarray, bias: np.ndarray, g: np.ndarray):
        self.g_mps2 = np.asarray(g, dtype=float)
        self._g = self.g_mps2.tolist()
        self._offset = [0.0] * 6
        self.gp = np.zeros(13)          # [m, m c, g, bias in use]: what the compiled cycle reads (service.kernel)
        self.carry(mass_kg, (float(mass_kg) * np.asarray(cog_m, dtype=float)).tolist(), bias)

    @classmethod
    def from_config(cls, section: GravityConfig) -> GravityCompensator:
        p = section.payload_sets()[0]
        return cls(p.mass_kg, np.array(p.cog_mm) / 1000.0, np.array(p.bias), np.array(section.g_mps2))

    def carry(self, mass_kg: float, mc_kgm, set_bias) -> None:
        """The payload now: mass m (kg), m c (kg m, sensor frame) and its set's bias (six floats); the
        tare's offset stays."""
        self.mass = float(mass_kg)
        self._mc = [float(v) for v in mc_kgm]
        self._set_bias = [float(v) for v in set_bias]
        self._bias = [b + o for b, o in zip(self._set_bias, self._offset)]
        gp = self.gp
        gp[0] = self.mass
        gp[1:4] = self._mc
        gp[4:7] = self._g
        gp[7:13] = self._bias

    def payload_wrench(self, R_sensor) -> list[float]:
        """[F_g; T_g] in sensor axes for the sensor orientation ``R_sensor`` (3x3, base; array or lists)."""
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = (
            R_sensor.tolist() if isinstance(R_sensor, np.ndarray) else R_sensor)
        gx, gy, gz = self._g
        ux = r00 * gx + r10 * gy + r20 * gz               # R^T g
        uy = r01 * gx + r11 * gy + r21 * gz
        uz = r02 * gx + r12 * gy + r22 * gz
        m = self.mass
        cx, cy, cz = self._mc                             # T_g = (m c) x (R^T g)
        return [m * ux, m * uy, m * uz, cy * uz - cz * uy, cz * ux - cx * uz, cx * uy - cy * ux]

    def compensate(self, wrench, R_sensor) -> list[float]:
        """The external wrench (sensor axes, six floats) from a reading."""
        return [w - b - g for w, b, g in zip(wrench, self._bias, self.payload_wrench(R_sensor))]

    def tare(self, wrench, R_sensor) -> None:
        """Take the current external wrench as the new zero (adds it to the tare's offset of the bias)."""
        self._offset = [o + e for o, e in zip(self._offset, self.compensate(wrench, R_sensor))]
        self.carry(self.mass, self._mc, self._set_bias)

    @property
    def bias(self) -> np.ndarray:
        """The bias in use: the set's bias plus the tare's offset."""
        return np.array(self._bias)

    @property
    def mc(self) -> np.ndarray:
        """m c, kg m (sensor frame)."""
        return np.array(self._mc)

    @property
    def cog(self) -> np.ndarray:
        """The centre of gravity, m (sensor frame; zero for no mass)."""
        return self.mc / self.mass if self.mass > 0 else np.zeros(3)
