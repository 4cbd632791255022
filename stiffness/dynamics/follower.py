"""The modes followed in the running service: each mode's frequency found from the arm's own ringing in the
cut, and handed to the structure and the observer (``dynamics.observer.follow``; docs/accelerometer.md,
"Following the modes").

A mode whose frequency is off cannot be corrected by a fixed observer (`stiffness.dynamics.observer`); the
ringing the arm shows after an entry says where the mode is. Each cycle, for mode k (direction phi_k,
frequency f_k, damping zeta_k as configured):

    m_k = phi_k . m                      the arm's deflection in the band (`observer_law`'s m: the acceleration
                                         through B / s^2 less L B of the nominal TCP; no correction in it)
    v_k = L B (phi_k . x_s)(t - h)       the model's static deflection through the same band, as the observer
                                         takes the model's (x_s the structure's input, `structure_law`'s u)
    y_j = H(f_j, zeta_k) v_k             a bank of candidates f_j = f_k (1 + STEP)^j, from f_k / (1 + range)
                                         to f_k (1 + range) (``follow_range``)

and, forgetting with the time constant ``follow_window_ms``, each candidate's least-squares misfit with its
own gain (the static model's scale is not the question here):

    J_j = S_mm - S_my,j^2 / S_yy,j

A frequency is read every `DECIDE_MS` when the candidates disagree: the best misfit is below the worst by
`MIN_CONTRAST` of the signal (S_mm), it explains `MIN_EXPLAINED` of it, and it is not at the bank's edge;
a parabola through the best and its neighbours (in log f) places it between candidates. Taken when
`AGREE` readings in a row lie within `AGREE_WITHIN` of each other and their mean is more than
`AGREE_WITHIN` from the frequency in use: the structure's and the observer's parameters are then those of
their sections with the new frequency (their own `params`, written in place into the terms the cycle runs,
the compiled cycle's memory). A quasi-static load leaves every candidate alike (each has unit static gain):
no reading, nothing changes.

The follower runs in the cycle's process after the cycle, in Python (about 16 us a cycle for two modes,
`benchmarks/bench_dynamics_cost.py`); it reads nothing until the observer's band has settled after a start.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from scipy import signal

from .structure import mode_biquad

DECIDE_MS = 20.0
MIN_CONTRAST = 0.25     # (J_worst - J_best) / S_mm: the frequency matters to what the arm did
MIN_EXPLAINED = 0.6     # 1 - J_best / S_mm
AGREE, AGREE_WITHIN = 4, 0.02
STEP = 0.02             # the candidates' spacing, relative


@dataclass
class Followed:
    """One mode's frequency as the follower reads it."""

    configured_hz: float
    hz: float                               # in use
    readings: deque = field(default_factory=lambda: deque(maxlen=AGREE))
    changes: int = 0


class ModeBank:
    """One mode's bank of candidates (module docstring): ``push`` each cycle, ``reading`` the frequency the
    arm's ringing shows, or None."""

    def __init__(self, hz: float, damping: float, band_sos: np.ndarray, horizon: int, period_s: float,
                 span: float, window_s: float):
        n = round(math.log1p(span) / math.log1p(STEP))
        self.hz = hz * (1.0 + STEP) ** np.arange(-n, n + 1)
        c = np.array([mode_biquad(f, damping, period_s) for f in self.hz])
        self.b0, self.b1, self.b2, self.a1, self.a2 = c.T.copy()
        self.z0, self.z1 = np.zeros(len(self.hz)), np.zeros(len(self.hz))
        self.sos = np.asarray(band_sos, dtype=float)                    # L B, scipy's sections
        self.band = [(b0, b1, b2, a1, a2) for b0, b1, b2, _, a1, a2 in self.sos.tolist()]
        self.zb = [[0.0, 0.0] for _ in self.band]
        self.line: deque[float] = deque(maxlen=horizon + 1)
        self.lam = math.exp(-period_s / window_s)
        self.smm, self.smy, self.syy = 0.0, np.zeros(len(self.hz)), np.zeros(len(self.hz))
        self.started = False

    def restart(self) -> None:
        self.started = False
        self.line.clear()
        self.smm, self.smy[:], self.syy[:] = 0.0, 0.0, 0.0

    def push(self, u: float, m: float) -> None:
        """This cycle's static deflection along the mode (``u``, the structure's input) and the arm's deflection
        along it in the band (``m``)."""
        if not self.started:                 # the band's filters steady on this u, the bank at rest
            self.zb = (signal.sosfilt_zi(self.sos) * u).tolist()
            self.z0[:], self.z1[:] = 0.0, 0.0
            self.started = True
            return
        self.line.append(u)
        v = self.line[0]
        for (b0, b1, b2, a1, a2), z in zip(self.band, self.zb):
            y = b0 * v + z[0]
            z[0] = b1 * v - a1 * y + z[1]
            z[1] = b2 * v - a2 * y
            v = y
        y = self.b0 * v + self.z0
        self.z0 = self.b1 * v - self.a1 * y + self.z1
        self.z1 = self.b2 * v - self.a2 * y
        lam = self.lam
        self.smm = lam * self.smm + m * m
        self.smy = lam * self.smy + m * y
        self.syy = lam * self.syy + y * y

    def reading(self) -> float | None:
        """The frequency (Hz) the candidates agree on, or None (module docstring)."""
        if self.smm <= 0.0 or not np.all(self.syy > 0.0):
            return None
        j = self.smm - self.smy ** 2 / self.syy
        best = int(np.argmin(j))
        if (j.max() - j[best]) < MIN_CONTRAST * self.smm or j[best] > (1.0 - MIN_EXPLAINED) * self.smm:
            return None
        if best == 0 or best == len(j) - 1:
            return None
        a, b, c = j[best - 1], j[best], j[best + 1]
        curve = a - 2.0 * b + c
        shift = 0.5 * (a - c) / curve if curve > 0.0 else 0.0
        return float(self.hz[best] * (1.0 + STEP) ** shift)


class Follower:
    """The modes of a structure and an observer followed together (module docstring).

    ``apply(hz)`` is given the frequencies in use (one per mode) when they change: it rewrites the parameters
    of the terms the cycle runs."""

    def __init__(self, modes, band_sos: np.ndarray, horizon: int, period_s: float, span: float, window_s: float,
                 apply):
        self.modes = [Followed(m.hz, m.hz) for m in modes]
        self.directions = np.array([m.direction for m in modes])
        self.banks = [ModeBank(m.hz, m.damping, band_sos, horizon, period_s, span, window_s) for m in modes]
        self.every = max(1, round(DECIDE_MS / 1000.0 / period_s))
        self.n = 0
        self.apply = apply
        self.fresh = True

    def restart(self) -> None:
        """The accelerometer's samples stopped or the states restarted: what the banks held says nothing now
        (once: it is called every cycle the observer is off)."""
        if self.fresh:
            return
        for b, f in zip(self.banks, self.modes):
            b.restart()
            f.readings.clear()
        self.fresh = True

    def step(self, u, m) -> list[Followed]:
        """This cycle's static deflection along each mode (``u``, the structure's inputs) and the arm's band
        deflection ``m`` (3,); returns the modes whose frequency changed (after `apply`)."""
        self.fresh = False
        mk = self.directions @ np.asarray(m, dtype=float)
        for bank, uk, mkk in zip(self.banks, u, mk):
            bank.push(float(uk), float(mkk))
        self.n += 1
        if self.n % self.every:
            return []
        changed = []
        for bank, f in zip(self.banks, self.modes):
            r = bank.reading()
            if r is None:
                f.readings.clear()
                continue
            f.readings.append(r)
            if len(f.readings) < AGREE:
                continue
            lo, hi = min(f.readings), max(f.readings)
            mean = sum(f.readings) / len(f.readings)
            if hi - lo <= AGREE_WITHIN * mean and abs(mean - f.hz) > AGREE_WITHIN * f.hz:
                f.hz = mean
                f.changes += 1
                changed.append(f)
        if changed:
            self.apply([f.hz for f in self.modes])
        return changed
