"""Process force of an end mill that follows the feed direction (the paper's Sec. V milling test).

The force on the cutter, base axes, at time t (s since the cut started):

    F(t) = e(t) m(t) [ -F_f t(phi) + F_n n(phi) + F_a a ]

t(phi)  unit feed direction at the path angle phi(t); the feed force opposes the motion
n(phi)  unit normal in the circle's plane pushing the tool away from the wall (towards the centre
        when ``normal_toward_center``)
a       unit tool-axis direction out of the workpiece (minus the tool's z axis)
e(t)    engagement: 0 before the cut; rises over the time the cutter needs to travel its diameter
        (smoothstep) with an impact overshoot (1 + o exp(-t / tau)); falls linearly to 0 over
        ``exit_s`` once the circle is closed
m(t)    tooth passing: (1 + A sin(2 pi f_z t)) (1 + v n_k), f_z = teeth * rpm / 60, n_k a seeded
        standard normal per tooth pass k = floor(f_z t) (chip-load variation)

Units: N, s. The force is a pure function of t and the path geometry, so two runs with the same seed
see the same trace.
"""

from __future__ import annotations

import numpy as np

from .scenario import MillingConfig

N_TOOTH_VARIATIONS = 1 << 16


class MillingForce:
    """The force model of one end mill.

    Parameters
    ----------
    cfg : MillingConfig
    feed_mm_s : float
        Feed along the path (sets the entry time, diameter / feed).
    cut_s : float
        Duration of the cut (one circle).
    """

    def __init__(self, cfg: MillingConfig, feed_mm_s: float, cut_s: float):
        self.Ff, self.Fn, self.Fa = cfg.feed_force_N, cfg.normal_force_N, cfg.axial_force_N
        self.normal_sign = -1.0 if cfg.normal_toward_center else 1.0
        self.f_tooth = cfg.teeth * cfg.spindle_rpm / 60.0
        self.amp = cfg.tooth_amplitude
        self.overshoot, self.tau = cfg.entry_overshoot, cfg.entry_tau_s
        self.entry_s = cfg.tool_diameter_mm / feed_mm_s
        self.exit_s = cfg.exit_s
        self.cut_s = float(cut_s)
        self.chip = 1.0 + cfg.variation * np.random.default_rng(cfg.seed).standard_normal(N_TOOTH_VARIATIONS)

    @property
    def end_s(self) -> float:
        """Time (s since the cut started) after which the force is zero."""
        return self.cut_s + self.exit_s

    def engagement(self, t: np.ndarray) -> np.ndarray:
        """e(t), dimensionless."""
        t = np.asarray(t, dtype=float)
        x = np.clip(t / self.entry_s, 0.0, 1.0)
        rise = x * x * (3.0 - 2.0 * x) * (1.0 + self.overshoot * np.exp(-np.maximum(t, 0.0) / self.tau))
        fall = np.clip(1.0 - (t - self.cut_s) / self.exit_s, 0.0, 1.0)
        return np.where(t < 0.0, 0.0, rise * fall)

    def modulation(self, t: np.ndarray) -> np.ndarray:
        """m(t), dimensionless."""
        t = np.asarray(t, dtype=float)
        k = np.floor(np.maximum(t, 0.0) * self.f_tooth).astype(np.int64) % N_TOOTH_VARIATIONS
        return (1.0 + self.amp * np.sin(2 * np.pi * self.f_tooth * t)) * self.chip[k]

    def force(self, t: np.ndarray, tangent: np.ndarray, outward: np.ndarray, axis_out: np.ndarray) -> np.ndarray:
        """F(t) (N, base axes), (N, 3) for arrays of times and the path's unit vectors at those times."""
        s = (self.engagement(t) * self.modulation(t))[..., None]
        return s * self.nominal(tangent, outward, axis_out)

    def nominal(self, tangent: np.ndarray, outward: np.ndarray, axis_out: np.ndarray) -> np.ndarray:
        """The bracket of F(t): the force at full engagement without the tooth passing (N)."""
        return -self.Ff * tangent + self.normal_sign * self.Fn * outward + self.Fa * axis_out
