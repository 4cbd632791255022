"""What a force and path record excites (`stiffcomp modes`, docs/dynamics.md "What a record excites").

Both tests ask of a part of the identified model (`stiffness.dynamics.modes`): how much more of the
deflection is left unexplained without it (dRSS, the other parts solved again), against what the record's
noise alone would let the fit explain with it.

The noise floor: P, the mean periodogram ordinate (2 / N) |R(f)|^2 of the fit's residual R over `BAND_HZ`,
where modes are looked for. For white noise of variance s^2 each ordinate is s^2 chi^2_2: mean P = 2 s^2,
and P(ordinate > x P) = exp(-x). A mode fitted to noise alone explains about the largest of the M
ordinates it could pick (the band's, along three directions), which passes x P with probability
M exp(-x); so noise lends a fitted mode more than T = ln(M / `ALPHA`) P with probability `ALPHA` only
(T = 20.4 P for a tap test of 4 s at 1 kHz).

* **A mode** k is in the record when leaving it out (the compliance and offset solved again, the other
  modes and the lag kept) leaves more than T P_k, P_k along its direction.
* **A force direction** (a base axis x, y, z: what a hammer is swung along, what a dynamometer reads) is
  excited when leaving the force along it out of the model (the compliance's column; the modes, the lag,
  the other columns and the offset kept or solved again) leaves more than T P, P the mean over the axes.
  Its three coefficients alone would take about 3 s^2 = 1.5 P of noise, but the modes were fitted with
  them, and noise lends those up to T P; a direction the force does not change along has no figure.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import signal

AXES = ("x", "y", "z")
BAND_HZ = (3.0, 60.0)    # where modes are looked for
MIN_RATE_HZ = 2.0 * BAND_HZ[1]   # a record's sample rate must cover that band
ALPHA = 1e-6             # the chance, on noise alone, of calling a direction excited or a mode seen


def band_top(period: float) -> float:
    """The top of the band where modes are looked for, below the record's Nyquist frequency."""
    return min(BAND_HZ[1], 0.45 / period)


def zero_phase(x: np.ndarray, period: float, hz, btype: str) -> np.ndarray:
    sos = signal.butter(2, hz, btype=btype, fs=1.0 / period, output="sos")
    return signal.sosfiltfilt(sos, x, axis=0)


@dataclass
class Excitation:
    """Per base axis, what the force along it explains in noise-floor units (None: the force does not change
    along it), and the threshold T (module docstring)."""

    ratio: dict[str, float | None]
    threshold: float

    def excited(self) -> list[str]:
        return [a for a, r in self.ratio.items() if r is not None and r > self.threshold]

    def describe(self) -> str:
        """``excites x (9.3e+03 P); not y, z (no force along them)``."""
        yes = self.excited()
        weak = [f"{a} ({r:.3g} P)" for a, r in self.ratio.items() if r is not None and a not in yes]
        none = [a for a, r in self.ratio.items() if r is None]
        no = weak + ([f"{', '.join(none)} (no force along {'them' if len(none) > 1 else 'it'})"] if none else [])
        return (f"excites {', '.join(f'{a} ({self.ratio[a]:.3g} P)' for a in yes) or 'no direction'}"
                + (f"; not {', '.join(no)}" if no else ""))

    def floor(self) -> str:
        """What P is and what noise alone reaches, for a message."""
        return f"P: the residual's noise floor; noise alone lends a fitted mode up to {self.threshold:.3g} P"

    def to_json(self) -> dict:
        return {"explains": {a: None if r is None else round(r, 3) for a, r in self.ratio.items()},
                "threshold": round(self.threshold, 3), "excited": self.excited()}


def mode_threshold(n_samples: int, period: float) -> float:
    """ln(M / ALPHA): what a mode fitted to noise alone explains, in noise-floor units, at most (module docstring)."""
    bins = np.fft.rfftfreq(n_samples, period)
    m = 3 * int(np.count_nonzero((bins >= BAND_HZ[0]) & (bins <= band_top(period))))
    return float(np.log(max(m, 1) / ALPHA))


def noise_floor(residual: np.ndarray, period: float, direction: np.ndarray) -> float:
    """P: the mean periodogram ordinate (2 / N) |R(f)|^2 of the residual along ``direction`` over the band (m^2)."""
    r = residual @ np.asarray(direction, dtype=float)
    f = np.fft.rfftfreq(len(r), period)
    inside = (f >= BAND_HZ[0]) & (f <= band_top(period))
    return float(np.mean(2.0 / len(r) * np.abs(np.fft.rfft(r - r.mean())[inside]) ** 2))
