"""The ramp from one model's prediction to another's, after a reload of a model with the same structure.

For ``n`` cycles both predictors run on the same compensated wrench, and the deflection moves
linearly from the old model's to the new one's:

    dX_k = dX_old + (k / n) (dX_new - dX_old),     k = 1 .. n

so the correction follows the new parameters without a step (the limiter's rate limit still holds on
top). The new predictor is the primary one meanwhile: its sensor rotation serves the gravity
compensation and the wrench in base axes, its Jacobian the correction. After the last cycle of the
ramp the compensator's predictor is the new one alone (`PredictorRamp` hands itself over through
``on_done``), and the old one is dropped.

The new predictor's history terms (hysteresis) start at their defined state, as after a tare.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .compensation import FastPredictor


class PredictorRamp:
    """Two predictors blended over ``cycles`` cycles; used in place of a `FastPredictor`.

    The compensator runs its Python path while a ramp lasts (``kernel`` is None); each predictor runs its
    own compiled form when it has one.

    Parameters
    ----------
    old, new : FastPredictor (or a PredictorRamp still ramping)
        ``new`` must have run `kinematics` at the current joint positions.
    cycles : int
        Length of the ramp in cycles (``limits.fault_ramp_s`` / the period).
    on_done : callable () -> None
        Called in the ramp's last cycle: puts ``new`` in the ramp's place.
    """

    kernel = None

    def __init__(self, old: FastPredictor, new: FastPredictor, cycles: int, on_done: Callable[[], None]):
        self.old, self.new = old, new
        self.cycles = max(int(cycles), 1)
        self.cycles_done = 0
        self.on_done = on_done
        self._w_sensor = [0.0] * 6

    def __getattr__(self, name: str):
        # R_s, p_s, J, tau_s ... of the primary (new) predictor; only attributes this class lacks land here
        return getattr(self.new, name)

    @property
    def fraction(self) -> float:
        """How far the ramp has come, 0 .. 1."""
        return self.cycles_done / self.cycles

    def kinematics(self, q_rad: np.ndarray) -> None:
        self.old.kinematics(q_rad)
        self.new.kinematics(q_rad)

    def carry(self, payload_kg: float, cog_m, g_mps2) -> None:
        self.old.carry(payload_kg, cog_m, g_mps2)
        self.new.carry(payload_kg, cog_m, g_mps2)

    def carry_payload(self, mass_kg: float, mc_kgm) -> None:
        self.old.carry_payload(mass_kg, mc_kgm)
        self.new.carry_payload(mass_kg, mc_kgm)

    def wrench_base(self, w_sensor) -> list[float]:
        self._w_sensor = w_sensor
        return self.new.wrench_base(w_sensor)

    def deflection(self, w_base, dt: float = 0.0) -> np.ndarray:
        """The blended deflection of one cycle (call once per cycle, after `wrench_base`)."""
        d_new = self.new.deflection(w_base, dt)
        d_old = self.old.deflection(self.old.wrench_base(self._w_sensor), dt)
        self.cycles_done = k = min(self.cycles_done + 1, self.cycles)
        if k == self.cycles:
            self.on_done()
        return d_old + (k / self.cycles) * (d_new - d_old)

    def reset_history(self) -> None:
        self.old.reset_history()
        self.new.reset_history()

    def correction(self, q_rad: np.ndarray, dX: np.ndarray) -> np.ndarray:
        return self.new.correction(q_rad, dX)
