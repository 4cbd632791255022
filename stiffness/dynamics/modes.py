"""Commissioning: the structure's modes identified from a recorded force and path (`stiffcomp modes DATA`).

The record (CSV, `read_record`): the time t_s, the force at the tool fx_N, fy_N, fz_N (base axes: a
dynamometer's, a tap test's hammer, or the HIL's process force) and the TCP's deflection from its path
dx_mm, dy_mm, dz_mm (base axes: a laser tracker's, or the HIL's robot stub). The model is the structure's
(`stiffness.dynamics.structure`) on a static compliance C (3 x 3, m/N) and an offset b, the force through
the arm's own lag L (a critically damped low-pass, (1 + s L / 2)^-2: the joints do not follow the tooth
passing; its delay at low frequency is L):

    d(t) = R[ C F_L(t) ] + b,     R[x] = x + sum_k phi_k (H_k (phi_k . x) - phi_k . x)

with each H_k the mode (f_k, zeta_k) as the service runs it. The fit:

1. L, C and b of the static part alone (L on a grid, C and b by least squares for each);
2. the modes' directions from the principal axes of what that leaves (band-passed), their frequencies from
   the peaks of its spectrum along them;
3. f_k, zeta_k, L and the directions' common rotation by nonlinear least squares (scipy.optimize), C and
   b solved linearly inside it for each guess (variable projection), the biquads of `Structure.respond`
   simulating the record.

A mode the record does not show, and a record whose force excites no direction above its noise, are
refused (`stiffness.dynamics.excitation`: what each explains against the record's noise floor). The result
says which force directions the record excites, how much of the deflection the identified structure
explains, against the static fit alone, and `figure` plots the identified response over the measured one. ``to_config`` is the
``dynamics.structure`` section for the service config.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy import optimize, signal
from scipy.spatial.transform import Rotation

from ..errors import DataError
from ..units import M_TO_MM, MM_TO_M
from .excitation import (
    AXES,
    BAND_HZ,
    MIN_RATE_HZ,
    Excitation,
    band_top,
    mode_threshold,
    noise_floor,
    zero_phase,
)
from .records import check_whole, read_columns
from .structure import ModeConfig, Structure

FORCE = ("fx_N", "fy_N", "fz_N")
DEFLECTION = ("dx_mm", "dy_mm", "dz_mm")
SLOW_HZ = 2.0            # the static fit's low-pass
MIN_SAMPLES = 200


@dataclass
class Record:
    """A force and a path on a uniform time grid: t (s), force (N, 3; N), deflection (N, 3; m).

    ``band``: the deflection was measured through these second-order sections (a cut's trace: the
    accelerometer's band, `stiffness.dynamics.from_cut`), so the model's response is taken through them too
    (`filtered`); None: the deflection itself (a tap test's)."""

    t: np.ndarray
    force: np.ndarray
    deflection: np.ndarray
    source: str = "<record>"
    band: np.ndarray | None = None

    @property
    def period(self) -> float:
        return float(self.t[1] - self.t[0])

    def filtered(self, x: np.ndarray) -> np.ndarray:
        """A response ``x`` (N, 3) as the record's deflection saw it: through ``band`` from its steady state."""
        if self.band is None:
            return x
        zi = signal.sosfilt_zi(self.band)[:, :, None] * x[:1][None, :, :]
        return signal.sosfilt(self.band, x, axis=0, zi=zi)[0]


def read_record(path: str | Path) -> Record:
    """The record CSV (module docstring); resampled to its median step when the steps vary by more than 1 %.
    DataError for a file cut off in its last line, or a sample rate below `MIN_RATE_HZ` (t_s in ms?)."""
    check_whole(path)
    cols = read_columns(path, ("t_s", *FORCE, *DEFLECTION), what="force and path record")
    t = cols["t_s"]
    step = float(np.median(np.diff(t)))
    if step * MIN_RATE_HZ > 1.0:
        hint = ("; is t_s in milliseconds? it is in seconds (1 ms rows: steps of 0.001)"
                if step * MIN_RATE_HZ <= 1000.0 else "")
        raise DataError(f"{path}: column t_s: the rows are {step:g} s apart ({1.0 / step:.3g} samples a second); "
                        f"the modes are looked for at {BAND_HZ[0]:g}-{BAND_HZ[1]:g} Hz, which needs at least "
                        f"{MIN_RATE_HZ:g} a second{hint}")
    force = np.column_stack([cols[c] for c in FORCE])
    d = np.column_stack([cols[c] for c in DEFLECTION]) * MM_TO_M
    return uniform(Record(t, force, d, str(path)))


def uniform(rec: Record) -> Record:
    """``rec`` on a uniform grid (linear interpolation at the median step, when the steps vary by > 1 %)."""
    dt = np.diff(rec.t)
    step = float(np.median(dt))
    if np.ptp(dt) <= 0.01 * step:
        return rec
    t = np.arange(rec.t[0], rec.t[-1], step)
    f = np.column_stack([np.interp(t, rec.t, rec.force[:, k]) for k in range(3)])
    d = np.column_stack([np.interp(t, rec.t, rec.deflection[:, k]) for k in range(3)])
    return Record(t, f, d, rec.source)


@dataclass
class Identified:
    """What the identification found: the structure (modes, lag), the static compliance and the fit."""

    structure: Structure
    compliance: np.ndarray                  # C (3, 3), m/N
    offset: np.ndarray                      # b (3,), m
    explained: float                        # share of the deflection's variance (about its mean) explained
    explained_static: float                 # the same for the static fit alone (no modes, no lag)
    rms_mm: float                           # the residual's RMS
    model: np.ndarray = field(repr=False)   # the identified response (N, 3), m
    static: np.ndarray = field(repr=False)  # the static fit alone (N, 3), m
    excitation: Excitation | None = None    # which force directions the record excites (`excitation`)
    evidence: list[float] = field(default_factory=list)   # per mode: what it explains, in noise-floor units

    def to_config(self) -> dict:
        """The service config's ``dynamics.structure`` section."""
        s = self.structure.cfg
        return {"modes": [{"hz": round(m.hz, 3), "damping": round(m.damping, 4),
                           "direction": [round(x, 5) for x in m.direction]} for m in s.modes],
                "lag_ms": round(s.lag_ms, 2)}


def _structure(hz, zeta, frame, n, lag_s) -> Structure:
    modes = [ModeConfig(hz=float(hz[k]), damping=float(zeta[k]), direction=list(frame[:, k])) for k in range(n)]
    return Structure(Structure.Config(modes=modes, lag_ms=1000.0 * lag_s))


def _late(rec: Record, lag_s: float) -> np.ndarray:
    """F_L (N, 3): the force through the critically damped low-pass of delay L, from its steady state."""
    if lag_s <= 0.0:
        return rec.force
    w = 2.0 / lag_s
    b, a = signal.bilinear([w * w], [1.0, 2.0 * w, w * w], 1.0 / rec.period)
    return signal.lfilter(b, a, rec.force, axis=0, zi=signal.lfilter_zi(b, a)[:, None] * rec.force[:1])[0]


def _solve(rec: Record, st: Structure, lag_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """C, b (least squares) and the model's response for the structure ``st`` and lag, by variable projection."""
    A = _design(rec, st, lag_s)
    sol = _lstsq(A, rec.deflection.ravel())
    return sol[:9].reshape(3, 3), sol[9:], (A @ sol).reshape(-1, 3)


def response(rec: Record, st: Structure) -> np.ndarray:
    """The response (N, 3; m) of ``st`` (its modes and lag) to the record's force, its compliance and offset
    solved for the record: the structure at its best on it (`stiffness.dynamics.compare`)."""
    return _solve(rec, st, st.lag_s())[2]


def _design(rec: Record, st: Structure, lag_s: float) -> np.ndarray:
    """The model's columns over the record (3 N, 12): the response to each compliance C_ij (column 3 i + j),
    then the offset's three."""
    late = _late(rec, lag_s)
    n = len(rec.t)
    cols = []
    for i in range(3):                          # R[e_i F_j(t - L)]: the response to the compliance C_ij
        for j in range(3):
            x = np.zeros((n, 3))
            x[:, i] = late[:, j]
            cols.append(rec.filtered(st.respond(x, rec.period)).ravel())
    for i in range(3):
        e = np.zeros((n, 3))
        e[:, i] = 1.0
        cols.append(rec.filtered(e).ravel())
    return np.column_stack(cols)


def _lstsq(A: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The least-squares solution of A x = y, its columns scaled first (a zero column solves to 0)."""
    scale = np.abs(A).max(axis=0)
    scale[scale == 0] = 1.0
    return np.linalg.lstsq(A / scale, y, rcond=None)[0] / scale


def _static(rec: Record, lag_s: float) -> np.ndarray:
    """What the static part (C F_L + b, least squares) leaves of the deflection (N, 3)."""
    X = _static_columns(rec, lag_s)
    return rec.deflection - X @ np.linalg.lstsq(X, rec.deflection, rcond=None)[0]


def _static_columns(rec: Record, lag_s: float) -> np.ndarray:
    """The static part's columns (N, 4): the force through the lag, and a constant, as the record saw them."""
    late = _late(rec, lag_s)
    cols = np.column_stack([late, np.ones(len(rec.t))])
    if rec.band is None:
        return cols
    return np.column_stack([rec.filtered(np.repeat(c[:, None], 3, axis=1))[:, 0] for c in cols.T])


def _start(rec: Record, n_modes: int, max_lag_ms: float) -> tuple[np.ndarray, np.ndarray, float]:
    """The modes' frame (3, 3, orthonormal, det +1), frequencies (Hz) and the lag (s) to start from."""
    lags = np.arange(0.0, max_lag_ms + 1e-9, 1.0) / 1000.0
    lag = float(lags[np.argmin([np.sum(_static(rec, L) ** 2) for L in lags])])
    resid = _static(rec, lag)
    top = band_top(rec.period)
    band = zero_phase(resid, rec.period, (BAND_HZ[0], top), "bandpass")
    frame = np.linalg.svd(band, full_matrices=False)[2].T
    if np.linalg.det(frame) < 0:
        frame[:, 2] *= -1.0
    hz = []
    for k in range(n_modes):
        f, P = signal.welch(band @ frame[:, k], fs=1.0 / rec.period, nperseg=min(len(band), 2048))
        inside = (f >= BAND_HZ[0]) & (f <= top)
        hz.append(float(f[inside][np.argmax(P[inside])]))
    return frame, np.array(hz), lag


def identify(rec: Record, n_modes: int = 2, max_lag_ms: float = 30.0) -> Identified:
    """The structure behind ``rec`` with ``n_modes`` modes (1 - 3; module docstring). DataError when the force
    excites no direction above the noise, or a mode found is not in the record (`stiffness.dynamics.excitation`)."""
    if not 1 <= n_modes <= 3:
        raise ValueError(f"n_modes = {n_modes} must be 1, 2 or 3 (modes along orthogonal directions)")
    if len(rec.t) < MIN_SAMPLES:
        raise DataError(f"{rec.source}: {len(rec.t)} samples; the identification needs at least {MIN_SAMPLES}")
    if np.ptp(rec.force, axis=0).max() < 1e-6:
        raise DataError(f"{rec.source}: the force does not change; nothing excites the structure")
    st, lag = _fit(rec, n_modes, max_lag_ms)
    A = _design(rec, st, lag)
    sol = _lstsq(A, rec.deflection.ravel())
    C, b, model = sol[:9].reshape(3, 3), sol[9:], (A @ sol).reshape(-1, 3)
    threshold = mode_threshold(len(rec.t), rec.period)
    exc = _excitation(rec, A, rec.deflection - model, threshold)
    if not exc.excited():
        raise DataError(f"{rec.source}: the force {exc.describe()} ({exc.floor()}); nothing can be identified "
                        "from it (tap harder, or record with a quieter instrument)")
    evidence = _evidence(rec, st, model)
    unseen = [k for k, e in enumerate(evidence) if not e > threshold]
    if unseen:
        raise DataError(_unseen(rec, st, exc, evidence, unseen))
    X = _static_columns(rec, 0.0)
    static = X[:, :3] @ np.linalg.lstsq(X, rec.deflection, rcond=None)[0][:3]
    static = static + (rec.deflection - static).mean(axis=0)
    var = np.sum((rec.deflection - rec.deflection.mean(0)) ** 2)
    return Identified(st, C, b, 1.0 - np.sum((rec.deflection - model) ** 2) / var,
                      1.0 - np.sum((rec.deflection - static) ** 2) / var,
                      float(np.sqrt(np.mean(np.sum((rec.deflection - model) ** 2, axis=1)))) * M_TO_MM, model, static,
                      exc, evidence)


def _fit(rec: Record, n_modes: int, max_lag_ms: float) -> tuple[Structure, float]:
    """Steps 1-3 of the module docstring: the structure (modes ordered by frequency) and the lag (s)."""
    frame0, hz0, lag0 = _start(rec, n_modes, max_lag_ms)
    rot0 = Rotation.from_matrix(frame0)
    norm = np.sqrt(np.mean((rec.deflection - rec.deflection.mean(0)) ** 2))

    def unpack(x):
        hz, zeta = np.exp(x[:n_modes]), np.exp(x[n_modes:2 * n_modes])
        frame = (Rotation.from_rotvec(x[2 * n_modes:2 * n_modes + 3]) * rot0).as_matrix()
        return hz, zeta, frame, x[-1] / 1000.0

    def residual(x):
        hz, zeta, frame, lag = unpack(x)
        st = _structure(hz, zeta, frame, n_modes, max(lag, 0.0))
        return ((_solve(rec, st, max(lag, 0.0))[2] - rec.deflection) / norm).ravel()

    x0 = np.concatenate([np.log(hz0), np.log(np.full(n_modes, 0.05)), np.zeros(3), [1000.0 * lag0]])
    lo = np.concatenate([np.log(np.full(n_modes, 0.5)), np.log(np.full(n_modes, 1e-3)), -np.full(3, np.pi), [0.0]])
    hi = np.concatenate([np.log(np.full(n_modes, 0.45 / rec.period)), np.log(np.full(n_modes, 1.5)),
                         np.full(3, np.pi), [max_lag_ms]])
    fit = optimize.least_squares(residual, np.clip(x0, lo, hi), bounds=(lo, hi), x_scale="jac", max_nfev=200)
    hz, zeta, frame, lag = unpack(fit.x)
    order = np.argsort(hz)
    return _structure(hz[order], zeta[order], frame[:, order], n_modes, lag), lag


def _excitation(rec: Record, A: np.ndarray, residual: np.ndarray, threshold: float) -> Excitation:
    """Per base axis, what the force along it explains (its compliance column left out, the rest solved
    again), in units of the noise floor (`stiffness.dynamics.excitation`)."""
    y, rss = rec.deflection.ravel(), float(np.sum(residual ** 2))
    floor = sum(noise_floor(residual, rec.period, e) for e in np.eye(3)) / 3.0
    ratio: dict[str, float | None] = dict.fromkeys(AXES)
    for j, axis in enumerate(AXES):
        if np.ptp(rec.force[:, j]) > 0.0:
            keep = [c for c in range(A.shape[1]) if not (c < 9 and c % 3 == j)]
            ratio[axis] = (float(np.sum((y - A[:, keep] @ _lstsq(A[:, keep], y)) ** 2)) - rss) / floor
    return Excitation(ratio, threshold)


def _unseen(rec: Record, st: Structure, exc: Excitation, evidence: list[float], unseen: list[int]) -> str:
    """The refusal of a mode the record does not show: which, its evidence, what the record excites, what to do."""
    k, n = unseen[0], len(st.cfg.modes)
    m = st.cfg.modes[k]
    missing = [a for a in AXES if a not in exc.excited()]
    todo = f"ask for {n - len(unseen)} mode(s)" if len(unseen) < n else "no mode can be identified from it"
    return (f"{rec.source}: mode {k + 1} of {n} ({m.hz:.3f} Hz, damping {100 * m.damping:.2f} %, along "
            f"[{', '.join(f'{x:+.2f}' for x in m.direction)}]) is not in the record: it explains {evidence[k]:.3g} P "
            f"({exc.floor()}); the force {exc.describe()}; {todo}"
            + (f", or tap along {', '.join(missing)} too" if missing else ""))


def _evidence(rec: Record, st: Structure, model: np.ndarray) -> list[float]:
    """Per mode: how much more of the deflection is left without it (the compliance and offset solved again,
    the other modes and the lag kept), in units of the residual's noise floor along its direction."""
    residual = rec.deflection - model
    rss = float(np.sum(residual ** 2))
    out = []
    for k, mode in enumerate(st.cfg.modes):
        rest = [m for i, m in enumerate(st.cfg.modes) if i != k]
        if rest:
            left = rec.deflection - _solve(rec, Structure(Structure.Config(modes=rest, lag_ms=st.cfg.lag_ms)),
                                           st.lag_s())[2]
        else:
            left = _static(rec, st.lag_s())
        out.append((float(np.sum(left ** 2)) - rss) / noise_floor(residual, rec.period, np.array(mode.direction)))
    return out


def figure(found: Identified, rec: Record, window_s: float = 1.0, predicted: np.ndarray | None = None):
    """The identified response over the measured one: per mode, the deflection along its direction
    (measured, identified, the static fit alone, and ``predicted``, another structure's response, where given:
    `stiffness.dynamics.compare`) in the ``window_s`` with the most motion along it; and the spectrum of the
    deflection against the identified model's (matplotlib Figure)."""
    from matplotlib.figure import Figure

    from ..report.plots import legend_below

    modes = found.structure.cfg.modes
    fig = Figure(figsize=(12, 3.2 * (len(modes) + 1)), layout="constrained")
    axes = []
    n = max(int(window_s / rec.period), 10)
    for k, m in enumerate(modes):
        phi = np.array(m.direction)
        meas, mod, stat = (x @ phi * M_TO_MM for x in (rec.deflection, found.model, found.static))
        band = zero_phase(meas - meas.mean(), rec.period, (BAND_HZ[0], band_top(rec.period)), "bandpass")
        start = int(np.argmax(np.convolve(band ** 2, np.ones(n), "valid"))) if len(band) > n else 0
        sl = slice(start, start + n)
        ax = fig.add_subplot(len(modes) + 1, 1, k + 1)
        ax.plot(rec.t[sl], meas[sl], color="k", lw=1.0, label="measured")
        ax.plot(rec.t[sl], mod[sl], color="tab:green", lw=1.0, ls="--", label="identified (modes and lag)")
        ax.plot(rec.t[sl], stat[sl], color="tab:gray", lw=0.8, label="static fit alone")
        if predicted is not None:
            ax.plot(rec.t[sl], (predicted @ phi * M_TO_MM)[sl], color="tab:red", lw=0.9, ls=":",
                    label="the compared model's modes")
        ax.set_title(f"mode {k + 1}: {m.hz:.2f} Hz, {100 * m.damping:.1f} % damping, along "
                     f"[{', '.join(f'{x:+.2f}' for x in m.direction)}]")
        ax.set_xlabel("time, s")
        ax.set_ylabel("deflection along it, mm")
        ax.grid(alpha=0.3)
        axes.append(ax)
    ax = fig.add_subplot(len(modes) + 1, 1, len(modes) + 1)
    top = 0.0
    for x, color in ((rec.deflection, "k"), (found.model, "tab:green"),
                     *(((predicted, "tab:red"),) if predicted is not None else ())):
        f, P = signal.welch((x - x.mean(0)) * M_TO_MM, fs=1.0 / rec.period, nperseg=min(len(x), 2048), axis=0)
        ax.semilogy(f, P.sum(axis=1), color=color, lw=1.0)
        top = max(top, float(P.sum(axis=1).max()))
    ax.set_ylim(top * 1e-6, top * 3)
    for m in modes:
        ax.axvline(m.hz, color="tab:green", lw=0.6, ls=":")
    ax.set_xlim(0, min(60.0, 0.5 / rec.period))
    ax.set_xlabel("frequency, Hz")
    ax.set_ylabel("power of the deflection, mm²/Hz")
    ax.set_title(f"spectrum: measured (black), identified (green){', compared (red)' if predicted is not None else ''}; "
                 f"explains {100 * found.explained:.2f} % "
                 f"(the static fit alone {100 * found.explained_static:.2f} %)")
    ax.grid(alpha=0.3)
    legend_below(fig, *axes, ncols=4 if predicted is not None else 3)
    return fig
