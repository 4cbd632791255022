"""What any fixed observer can do when a mode's frequency is off (issue 52): the observer's transfer from the arm's
deflection error z to its correction, T(f) = G(f) L B(f), against the ideal e^((i - zeta) 2 pi f h) (the error
h later, ringing on), at the true frequency when the model's is 20 % high (f_model / 1.2) or 20 % low
(f_model / 0.8).

e = L B z is what the observer sees (docs/accelerometer.md, "The observer"); G is what it does with it. Designs:

* ``shipped``: `dynamics.observer` as the service runs it (`Observer.params`: the error and its difference,
  carried h ahead as the mode's free oscillation, the band's gain and phase undone at f_model);
* ``fir N``: N taps of e fitted by least squares to the ideal over [f_model / 1.2, f_model / 0.8], with a
  weight ``--out-weight`` on |T| below 2.5 Hz and above 35 Hz (where the static model's error, the box's bias
  and the teeth lie);
* ``kalman Q``: a steady Kalman filter of the mode (an oscillator at f_model driven by white acceleration of
  Q m/s^2 a cycle, a slow offset, the band's biquads modelled exactly, 0.1 um of noise on e), its state
  carried h ahead.

Printed per design: |T - ideal| at f_model / 1.2, f_model and f_model / 0.8 (the share of the ringing left),
the largest |T| below 2 Hz and above 35 Hz, and the largest |G| below 2 Hz (what e's own content there, which
is not L B z, is multiplied by). Frequency-domain, deterministic: one run is the figure.

    .venv/bin/python benchmarks/bench_observer_band.py [--hz 10 16] [--horizon-ms 5] [--taps 2 4 8]
                                                       [--kalman 0.01 0.1 1] [--out-weight 0.3]
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
from scipy import linalg, signal

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from stiffness.dynamics.observer import N_BIQUADS, Observer, band_sos

PERIOD_S = 1e-3
LOW = np.array([0.3, 0.5, 1.0, 1.5, 2.0])
HIGH = np.array([35.0, 50.0, 60.0, 100.0, 200.0])


def band(obs: Observer, f):
    return signal.sosfreqz(band_sos(obs.cfg.band_hz, obs.cfg.box_lowpass_hz, PERIOD_S)[1], worN=f,
                           fs=1.0 / PERIOD_S)[1]


def shipped(obs: Observer):
    """G(f) of the service's observer, from its own parameters."""
    p = obs.params(PERIOD_S)
    c, s = p[4 + 5 * N_BIQUADS + 3], p[4 + 5 * N_BIQUADS + 4]       # the mode's row: phi (3), c, s
    return lambda f: c + s * (1.0 - np.exp(-2j * np.pi * np.asarray(f) * PERIOD_S)) / PERIOD_S


def fir(obs: Observer, hz: float, taps: int, weight: float, h_s: float):
    z = lambda f: np.exp(-2j * np.pi * np.asarray(f) * PERIOD_S)
    fit = np.linspace(hz / 1.2, hz / 0.8, 60)
    out = np.concatenate([np.linspace(0.3, 2.5, 20), np.linspace(35.0, 200.0, 20)])
    a = np.vstack([np.array([band(obs, fit) * z(fit) ** j for j in range(taps)]).T,
                   weight * np.array([band(obs, out) * z(out) ** j for j in range(taps)]).T])
    b = np.concatenate([ideal(obs, fit, h_s), np.zeros(len(out))])
    c = np.linalg.lstsq(np.vstack([a.real, a.imag]), np.concatenate([b.real, b.imag]), rcond=None)[0]
    return lambda f: np.array([z(f) ** j for j in range(taps)]).T @ c


def cascade(biquads):
    """(A, B, C, D) of the biquads [b0, b1, b2, a1, a2] in series, two states each as the observer's law runs
    them (transposed direct form II: y = b0 u + z0, z0' = b1 u - a1 y + z1, z1' = b2 u - a2 y)."""
    n = 2 * len(biquads)
    a, b = np.zeros((n, n)), np.zeros(n)
    c_in, d_in = np.zeros(n), 1.0                   # this stage's input as c_in . x + d_in u
    for j, (b0, b1, b2, a1, a2) in enumerate(biquads):
        c_y, d_y = b0 * c_in, b0 * d_in
        c_y[2 * j] += 1.0
        a[2 * j], b[2 * j] = b1 * c_in - a1 * c_y, b1 * d_in - a1 * d_y
        a[2 * j, 2 * j + 1] += 1.0
        a[2 * j + 1], b[2 * j + 1] = b2 * c_in - a2 * c_y, b2 * d_in - a2 * d_y
        c_in, d_in = c_y, d_y
    return a, b, c_in, d_in


def kalman(obs: Observer, hz: float, damping: float, q: float, h: int):
    """G(f) of the steady Kalman filter (module docstring), the Riccati equation iterated to its fixed point."""
    w = 2.0 * math.pi * hz
    phi = linalg.expm(np.array([[0.0, 1.0], [-w * w, -2.0 * damping * w]]) * PERIOD_S)
    af, bf, cf, df = cascade(obs.filters(PERIOD_S)[3:])
    n = 3 + len(af)
    f_ = np.zeros((n, n))
    f_[:2, :2], f_[2, 2], f_[3:, 3:] = phi, math.exp(-PERIOD_S / 0.3), af
    f_[3:, 0] = f_[3:, 2] = bf
    hm = np.zeros((1, n))
    hm[0, 0] = hm[0, 2] = df
    hm[0, 3:] = cf
    r = 1e-7
    g = np.array([0.5 * PERIOD_S ** 2, PERIOD_S])
    qm = np.zeros((n, n))
    qm[:2, :2] = np.outer(g, g) * (q / r) ** 2
    qm[2, 2] = (1e-7 / r) ** 2
    p = qm.copy()
    for _ in range(50_000):
        nxt = f_ @ (p - p @ hm.T @ hm @ p / (hm @ p @ hm.T + 1.0)) @ f_.T + qm
        done = np.max(np.abs(nxt - p)) <= 1e-12 * max(1.0, np.max(np.abs(nxt)))
        p = nxt
        if done:
            break
    k = (p @ hm.T / (hm @ p @ hm.T + 1.0))[:, 0]
    m = (np.eye(n) - np.outer(k, hm[0])) @ f_
    out = np.zeros(n)
    out[:2] = np.linalg.matrix_power(phi, h)[0]

    def g_of(f):
        zs = np.exp(2j * np.pi * np.atleast_1d(f) * PERIOD_S)
        return np.array([out @ np.linalg.solve(z * np.eye(n) - m, k * z) for z in zs])
    return g_of


def ideal(obs: Observer, f, h_s: float):
    """The error h later, a ringing of the mode's damping at ``f``."""
    return np.exp((1j - obs.cfg.modes[0].damping) * 2.0 * np.pi * np.asarray(f) * h_s)


def row(name, g, obs, hz, h_s):
    at = np.array([hz / 1.2, hz, hz / 0.8])
    t = lambda f: g(f) * band(obs, f)
    err = np.abs(t(at) - ideal(obs, at, h_s))
    print(f"{name:>16} | {err[0]:5.2f} {err[1]:5.2f} {err[2]:5.2f} | {np.abs(t(LOW)).max():7.2f} "
          f"{np.abs(t(HIGH)).max():7.2f} | {np.abs(g(LOW)).max():8.1f}")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--hz", type=float, nargs="+", default=[10.0, 16.0], help="the model's mode frequencies")
    ap.add_argument("--damping", type=float, default=0.03)
    ap.add_argument("--horizon-ms", type=float, default=5.0)
    ap.add_argument("--taps", type=int, nargs="*", default=[2, 4, 8])
    ap.add_argument("--kalman", type=float, nargs="*", default=[0.01, 0.1, 1.0])
    ap.add_argument("--out-weight", type=float, default=0.3)
    args = ap.parse_args(argv)
    h = round(args.horizon_ms / 1000.0 / PERIOD_S)
    h_s = h * PERIOD_S
    for hz in args.hz:
        obs = Observer(Observer.Config(modes=[{"hz": hz, "damping": args.damping, "direction": [1, 0, 0]}],
                                       horizon_ms=args.horizon_ms))
        print(f"\nmodel {hz:g} Hz, horizon {1000 * h_s:g} ms: |T - ideal| at the true frequency {hz / 1.2:.2f} "
              f"(model +20 %), {hz:g}, {hz / 0.8:.2f} Hz (model -20 %); |T| below 2 Hz, above 35 Hz; |G| below 2 Hz")
        row("shipped", shipped(obs), obs, hz, h_s)
        for n in args.taps:
            row(f"fir {n}", fir(obs, hz, n, args.out_weight, h_s), obs, hz, h_s)
        for q in args.kalman:
            row(f"kalman {q:g}", kalman(obs, hz, args.damping, q, h), obs, hz, h_s)


if __name__ == "__main__":
    main()
