"""Signal conditioning of the wrench: spike rejection, then a low-pass in second-order sections.

`SosLowPass` is designed with scipy.signal (Butterworth or Bessel, order and cut-off from the config)
and steps one sample at a time with its state passed in and out, ``y, z = step(x, z)``, in
direct form II transposed, exactly as scipy.signal.sosfilt computes it. It can start in steady state
(scipy.signal.sosfilt_zi). `SpikeRejector` holds the last good value while a sample jumps by more
than a threshold, for at most ``max_held`` samples (a longer step is a real change of load).
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field
from scipy import signal

from stiffness.files.yaml_schema import Strict


class SpikeConfig(Strict):
    """``filter.spike``: a jump larger than these is a spike, held for at most ``max_held`` samples."""

    max_step_N: float = Field(300.0, gt=0)
    max_step_Nm: float = Field(30.0, gt=0)
    max_held: int = Field(3, ge=0, le=100)


class FilterConfig(Strict):
    """``filter``: the low-pass (its cut-off below half the cycle rate, checked with ``cycle``) and the
    spike rejector."""

    type: Literal["butterworth", "bessel", "none"] = "butterworth"
    order: int = Field(2, ge=1, le=8)
    cutoff_hz: float = Field(100.0, gt=0)
    spike: SpikeConfig = Field(default_factory=SpikeConfig)


class SosLowPass:
    """A low-pass over the six wrench channels.

    The state is a list with one ``[z1, z2]`` pair per section, each a list of ``channels`` floats:
    for six channels plain floats are faster than NumPy calls, and the cycle's budget is 100 µs.

    Parameters
    ----------
    sos : (S, 6) second-order sections (scipy.signal layout b0 b1 b2 a0 a1 a2, a0 = 1)
    channels : int
    """

    def __init__(self, sos: np.ndarray, channels: int = 6):
        self.sos = np.asarray(sos, dtype=float)
        self.channels = channels
        self._coef = [(float(s[0]), float(s[1]), float(s[2]), float(s[4]), float(s[5])) for s in self.sos]
        self._zi = [(float(z[0]), float(z[1])) for z in signal.sosfilt_zi(self.sos)]   # the unit step's
        self.state = self.zero_state()
        self.last_output: list[float] | None = None     # None before the first sample

    @classmethod
    def design(cls, kind: str, order: int, cutoff_hz: float, rate_hz: float) -> SosLowPass:
        """A low-pass from scipy.signal.iirfilter ("butterworth" or "bessel", phase-normalised), or a
        pass-through for "none"."""
        if kind == "none":
            return cls(np.array([[1.0, 0, 0, 1.0, 0, 0]]))
        ftype = {"butterworth": "butter", "bessel": "bessel"}.get(kind)
        if ftype is None:
            raise ValueError(f"unknown filter type {kind!r}")
        return cls(signal.iirfilter(order, cutoff_hz, btype="low", ftype=ftype, fs=rate_hz, output="sos"))

    @classmethod
    def from_config(cls, section: FilterConfig, period_s: float) -> SosLowPass:
        return cls.design(section.type, section.order, section.cutoff_hz, 1.0 / period_s)

    def zero_state(self) -> list[list[list[float]]]:
        """State of a filter at rest."""
        return [[[0.0] * self.channels, [0.0] * self.channels] for _ in self._coef]

    def steady_state(self, x) -> list[list[list[float]]]:
        """State of a filter that has seen the constant input ``x`` forever (scipy.signal.sosfilt_zi)."""
        x = [float(v) for v in x]
        return [[[z0 * v for v in x], [z1 * v for v in x]] for z0, z1 in self._zi]

    def continue_from(self, other: SosLowPass) -> None:
        """Take over from ``other`` (a reload with new parameters): start in the steady state of its last
        output, so this filter's output goes on from where ``other``'s left off instead of stepping.
        A filter that has seen no sample yet starts as ``other`` would, at the first sample.

        The first output is then y + b0 (x - y) per section chain, x the new sample and y the last output:
        it departs from y by a fraction of the noise, not by a step. Cheap (12 products per section): it
        runs in the cycle, between two samples."""
        if other.last_output is not None:
            self.state = self.steady_state(other.last_output)
            self.last_output = other.last_output

    def step(self, x, z: list) -> tuple[list[float], list]:
        """Filter one sample ``x`` (channels,) from state ``z``; returns (y, new state).

        Direct form II transposed per section, as scipy.signal.sosfilt computes it:
        y = b0 x + z1;  z1' = b1 x - a1 y + z2;  z2' = b2 x - a2 y.
        """
        out = []
        for (b0, b1, b2, a1, a2), (z1, z2) in zip(self._coef, z):
            y = [b0 * xi + zi for xi, zi in zip(x, z1)]
            out.append([[b1 * xi - a1 * yi + zi for xi, yi, zi in zip(x, y, z2)],
                        [b2 * xi - a2 * yi for xi, yi in zip(x, y)]])
            x = y
        return x, out

    def run(self, x: np.ndarray, z: list | None = None) -> tuple[np.ndarray, list]:
        """Filter a block (N, channels) sample by sample; returns (y, final state)."""
        z = self.zero_state() if z is None else z
        y = np.empty((len(x), self.channels))
        for n in range(len(x)):
            y[n], z = self.step(x[n].tolist(), z)
        return y, z

    def update(self, x) -> list[float]:
        """One sample with the filter's own state (the service's hot path)."""
        y, self.state = self.step(x, self.state)
        self.last_output = y
        return y


class SpikeRejector:
    """Replace single-sample spikes by the last accepted value.

    Parameters
    ----------
    max_step : (channels,) largest plausible change between two samples (N, Nm)
    max_held : int
        A jump that persists for more than this many samples is accepted as a real change.
    """

    def __init__(self, max_step, max_held: int = 3):
        self.max_step = [float(v) for v in max_step]
        self.max_held = int(max_held)
        self.last: list[float] | None = None
        self.held = 0
        self.rejected = 0

    @classmethod
    def from_config(cls, section: SpikeConfig) -> SpikeRejector:
        return cls([section.max_step_N] * 3 + [section.max_step_Nm] * 3, section.max_held)

    def update(self, x: list[float]) -> list[float]:
        """The accepted value for sample ``x`` (six floats)."""
        last = self.last
        if last is None:
            self.last = list(x)
            return self.last
        if self.held < self.max_held and any(abs(a - b) > m for a, b, m in zip(x, last, self.max_step)):
            self.held += 1
            self.rejected += 1
            return last
        self.held = 0
        self.last = list(x)
        return self.last
