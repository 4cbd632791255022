"""The arm's modes as the accelerometer sees them: the deflection the stages before predict, corrected by what
the arm actually does in the modes' band (docs/accelerometer.md, "The observer").

The force alone cannot tell the ringing's phase once a mode's frequency is off (docs/dynamics.md). The flange
accelerometer measures the tool's acceleration a = s^2 P (base axes, gravity and bias removed,
`service.accelerometer`), P = FK(q) + d the actual TCP: the joints' nominal TCP and the arm's deflection d.
Through a band-pass B around the modes (second-order high-pass at band_hz[0], a first-order one there too,
second-order low-pass at band_hz[1]) and the box's own low-pass L (second-order at box_lowpass_hz, modelled
Butterworth), both sides of

    e = (B / s^2) a_measured - B L (FK(q) + dX(t - h))  =  B L (d - dX(t - h))

are computable every cycle: the acceleration through B / s^2 (proper: B has four zeros at 0), the nominal TCP
FK(q) of the joints the PLC reported ``joints_lead_ms`` ago and the deflection dX the stages before predicted
h ago (``horizon_ms``; both delay lines), each for the instant the acceleration describes: the joints the PLC
reports are its commands, which the drives reach a cycle later, while the box's value is a cycle or two old
when the PLC reads it, so the joints lead the acceleration (in the HIL with the PLC at 1 ms, a lead of 2 to 5
cycles did about equally well and none did clearly better, docs/accelerometer.md; 3 ms is the default; FK(q)
at the wrong instant leaves the correction's own motion in e, up to 20 um a ms after an entry). h runs on to
the instant the correction is in the arm: the PLC commands it 1.5 cycles after the service's output and the
drives reach it a cycle later (5 ms with a 1 ms PLC, the default). So e is the model's error
in the band, without integrating the accelerometer's bias or noise below it (B's fourth-order zero at 0: a bias
left after the tare decays with the high-pass's time constant).

Each mode k (frequency f_k, damping zeta_k, direction phi_k) carries e's share e_k = phi_k . e forward to the
instant the correction reaches the joints, h later, as its own free oscillation, and undoes the band-pass's
gain and phase at f_k (|F|, arg F of the discrete filters):

    o_k = c_k e_k + s_k (e_k - e_k,last) / dt,   c_k + s_k D(w_k) = exp((i - zeta_k) w_k h) / F(w_k)
    dX <- dX + g sum_k phi_k o_k

with D(w) = (1 - exp(-i w dt)) / dt the difference's own response (it lags half a cycle: taken for the
derivative, it left the ringing 4 % off at 16 Hz). A ringing at f_k thus leaves the observer as it will be h
later, exactly; at another frequency it does not: the band's phase changes across the band, so a frequency
20 % off leaves 22-29 % of a 10 Hz ringing and 28-46 % of a 16 Hz one (`benchmarks/bench_observer_band.py`,
which shows that no fixed filter of e does much better without multiplying what e carries below 2 Hz, the
static model's error and the box's bias, docs/accelerometer.md). The gain g ramps between 0 and
1 over ``ramp_ms``: up when the accelerometer's samples arrive (its states started afresh: the positions' at
their steady state, the acceleration's at rest), down while they do not, holding the last o (the force-only path
then; no jump either way). After each start it first waits ``settle_ms``: the band's start is no motion of the
arm (a bias the tare has not yet taken, a move under way ring through the high-pass; in the HIL they put 0.13 mm
into the correction before the cut, docs/accelerometer.md, "The band's start").

With ``follow`` the modes' frequencies are followed in the cut (`stiffness.dynamics.follower`, built by
`follower`): the law keeps m = (B / s^2) a - L B FK(q), the arm's deflection in the band, apart for it (L B of
the model's dX runs on its own filters), and the follower hands the structure and this observer the arm's
frequencies (`with_frequencies`).

Real-time term: a `TwistTerm` whose law is `observer_law` (seven biquads an axis, the delay line, the modes),
on the Python and the compiled path; `feed_motion` writes the acceleration, the nominal TCP and whether the
samples arrive into its state each cycle.
"""

from __future__ import annotations

import math

import numpy as np
from pydantic import Field, field_validator, model_validator
from scipy import signal

from ..effects.terms import TwistTerm
from ..files.yaml_schema import Strict
from .base import DynamicsContext, Stage, biquad
from .follower import Follower
from .structure import ModeConfig, orthogonal

H_MAX = 100             # the delay line's length, cycles
MAX_HORIZON_MS = 7.0    # measured in the HIL (docs/accelerometer.md): 3-7 ms help, 12 ms and more made the exit worse
MAX_SAMPLE_MS = 3.0     # new values at least this often: measured good with one every 2 ms (a 1000 Hz box, a 1 ms
                        # task writing every other cycle); every 4-5 ms (a 200 Hz box, a 2 ms task) made the
                        # correction's error 4-10 x the static one's
N_BIQUADS = 7           # the acceleration's path: B / s^2 as [1 / (s^2 + ...), high-pass 1, low-pass 2]; the
                        # nominal TCP's and the model's: L, high-pass 2, high-pass 1, low-pass 2
RING, BIQ = 19, 19 + 3 * H_MAX
JOINTS = BIQ + 3 * 2 * N_BIQUADS        # the nominal TCP's delay line
MODEL = JOINTS + 3 * H_MAX              # L B of the model's dX(t - h) apart from the nominal TCP's: 3 x 4 x (z0, z1)
MEASURED = MODEL + 3 * 2 * 4            # m = (B / s^2) a - L B FK(q), the band's deflection of the arm (3)
SETTLED = MEASURED + 3                  # cycles since the (re)start: the gain rises after ``settle_ms``
STATE_SIZE = SETTLED + 1
MAX_LEAD_MS = 20.0      # the most joints_lead_ms takes
PER_MODE = 5            # phi (3), c_k, s_k (module docstring)


def observer_law(s, p, dX, dt):
    """dX (6,) += g sum_k phi_k o_k in place (module docstring). p = [K, h (cycles), ramp step, the joints' lead
    (cycles), 7 x (b0, b1, b2, a1, a2), K x (phi (3), c_k, s_k)]; s = [a (3), FK(q) (3), ok, started, g,
    ring position, o (3), e last (3), de (3), dX's ring (3 H_MAX), 3 x 7 x (z0, z1), FK(q)'s ring (3 H_MAX),
    3 x 4 x (z0, z1) (L B of dX's, apart), m (3), cycles since the start]; p ends with the settling's cycles."""
    n = int(p[0])
    h = int(p[1])
    lead = int(p[3])
    if s[6] > 0.5:
        if s[7] == 0.0:                          # (re)start: the line full of this dX, the filters steady
            for k in range(H_MAX):
                for i in range(3):
                    s[RING + 3 * k + i] = dX[i]
                    s[JOINTS + 3 * k + i] = s[3 + i]
            for i in range(3):                   # the acceleration's path at rest (its mean is 0, not
                for j in range(3):               # this value); the positions' at their steady state
                    s[BIQ + 14 * i + 2 * j] = 0.0
                    s[BIQ + 14 * i + 2 * j + 1] = 0.0
                for path in range(2):
                    u = s[3 + i] if path == 0 else dX[i]
                    for j in range(3, N_BIQUADS):
                        o = 4 + 5 * j
                        z = BIQ + 14 * i + 2 * j if path == 0 else MODEL + 8 * i + 2 * (j - 3)
                        b0, b1, b2, a1, a2 = p[o], p[o + 1], p[o + 2], p[o + 3], p[o + 4]
                        y = (b0 + b1 + b2) / (1.0 + a1 + a2) * u
                        s[z + 1] = b2 * u - a2 * y
                        s[z] = b1 * u - a1 * y + s[z + 1]
                        u = y
                s[13 + i] = 0.0
                s[MEASURED + i] = 0.0
            s[7] = 1.0
            s[9] = 0.0
            s[SETTLED] = 0.0
        pos = int(s[9])
        back = (pos - h) % H_MAX
        led = (pos - lead) % H_MAX
        for i in range(3):
            old = s[RING + 3 * back + i]
            s[RING + 3 * pos + i] = dX[i]
            s[JOINTS + 3 * pos + i] = s[3 + i]
            nominal = s[JOINTS + 3 * led + i]
            e = 0.0
            for path in range(3):               # B / s^2 a, L B FK(q), L B dX(t - h)
                u = s[i] if path == 0 else (nominal if path == 1 else old)
                first = 0 if path == 0 else 3
                for j in range(first, first + (3 if path == 0 else 4)):
                    o = 4 + 5 * j
                    z = BIQ + 14 * i + 2 * j if path < 2 else MODEL + 8 * i + 2 * (j - 3)
                    y = p[o] * u + s[z]
                    s[z] = p[o + 1] * u - p[o + 3] * y + s[z + 1]
                    s[z + 1] = p[o + 2] * u - p[o + 4] * y
                    u = y
                if path == 0:
                    e = u
                else:
                    e -= u
                if path == 1:
                    s[MEASURED + i] = e
            s[16 + i] = (e - s[13 + i]) / dt if dt > 0.0 else 0.0
            s[13 + i] = e
        s[9] = float((pos + 1) % H_MAX)
        for i in range(3):
            s[10 + i] = 0.0
        for k in range(n):
            o = 4 + 5 * N_BIQUADS + PER_MODE * k
            ek = p[o] * s[13] + p[o + 1] * s[14] + p[o + 2] * s[15]
            dek = p[o] * s[16] + p[o + 1] * s[17] + p[o + 2] * s[18]
            out = p[o + 3] * ek + p[o + 4] * dek
            for i in range(3):
                s[10 + i] += p[o + i] * out
        s[SETTLED] += 1.0
        if s[SETTLED] > p[4 + 5 * N_BIQUADS + PER_MODE * n]:
            s[8] = min(1.0, s[8] + p[2])
        else:                                   # the band's filters settling: their start is no motion of the arm
            s[8] = max(0.0, s[8] - p[2])
    else:
        s[7] = 0.0
        s[8] = max(0.0, s[8] - p[2])
    for i in range(3):
        dX[i] += s[8] * s[10 + i]


def band_filters(band_hz, box_lowpass_hz: float, period_s: float) -> np.ndarray:
    """(7, 5) the biquads [b0, b1, b2, a1, a2] of B / s^2 (three) and of L B (four) at ``period_s``, prewarped at
    the band's centre (module docstring; `band_sos` gives them as two cascades)."""
    lo, hi = band_hz
    centre = math.sqrt(lo * hi)
    wl, wh = 2.0 * math.pi * lo, 2.0 * math.pi * hi
    q = math.sqrt(2.0)
    low2 = biquad([wh * wh], [1.0, q * wh, wh * wh], period_s, centre)
    high1 = biquad([1.0, 0.0], [1.0, wl], period_s, centre)
    high2 = biquad([1.0, 0.0, 0.0], [1.0, q * wl, wl * wl], period_s, centre)
    over_s2 = biquad([1.0], [1.0, q * wl, wl * wl], period_s, centre)
    if box_lowpass_hz > 0.0:
        wb = 2.0 * math.pi * min(box_lowpass_hz, 0.45 / period_s)
        box = biquad([wb * wb], [1.0, q * wb, wb * wb], period_s)
    else:
        box = np.array([1.0, 0.0, 0.0, 0.0, 0.0])
    return np.array([over_s2, high1, low2, box, high2, high1, low2])


def band_sos(band_hz, box_lowpass_hz: float, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """(B / s^2, L B) as scipy's second-order sections: what turns a measured acceleration and a position into
    the band's deflection, e = (B / s^2) a - L B p."""
    f = band_filters(band_hz, box_lowpass_hz, period_s)
    sos = np.column_stack([f[:, :3], np.ones(len(f)), f[:, 3:]])
    return sos[:3], sos[3:]


class Observer(Stage):
    """``dynamics.observer``: the modes corrected by the accelerometer (module docstring)."""

    name = "observer"

    class Config(Strict):
        modes: list[ModeConfig] = Field(min_length=1, max_length=6)
        horizon_ms: float = Field(5.0, ge=0.0, le=MAX_HORIZON_MS)
        joints_lead_ms: float = Field(3.0, ge=0.0, le=MAX_LEAD_MS)
        band_hz: list[float] = Field(default_factory=lambda: [2.5, 40.0], min_length=2, max_length=2)
        box_lowpass_hz: float = Field(62.5, ge=0.0, le=5000.0)
        ramp_ms: float = Field(100.0, gt=0.0, le=10_000.0)
        settle_ms: float = Field(150.0, ge=0.0, le=10_000.0)   # after a (re)start, the gain rises after this
        follow: bool = False                # the modes' frequencies followed in the cut (`stiffness.dynamics.follower`)
        follow_range: float = Field(0.4, gt=0.0, le=0.6)            # the candidates: f / (1 + range) to f (1 + range)
        follow_window_ms: float = Field(400.0, ge=50.0, le=5000.0)  # the misfit's forgetting

        _orthogonal = field_validator("modes")(classmethod(lambda cls, v: orthogonal(v)))

        @model_validator(mode="after")
        def _band(self):
            lo, hi = self.band_hz
            if not (0.0 < lo < min(m.hz for m in self.modes) and max(m.hz for m in self.modes) < hi):
                raise ValueError(f"band_hz [{lo:g}, {hi:g}] must hold every mode's frequency, above 0")
            r = self.follow_range if self.follow else 0.0
            if not (lo < min(m.hz for m in self.modes) / (1.0 + r) and (1.0 + r) * max(m.hz for m in self.modes) < hi):
                raise ValueError(f"band_hz [{lo:g}, {hi:g}] must hold every frequency follow_range {r:g} lets a "
                                 "mode take")
            return self

    reads_motion = True

    def __init__(self, cfg):
        super().__init__(cfg)
        self.fed: list[TwistTerm] = []
        self.too_slow = False

    def filters(self, period_s: float) -> np.ndarray:
        """(7, 5) the biquads [b0, b1, b2, a1, a2] at ``period_s`` (`N_BIQUADS`' order; `band_filters`)."""
        return band_filters(self.cfg.band_hz, self.cfg.box_lowpass_hz, period_s)

    def params(self, period_s: float) -> np.ndarray:
        f = self.filters(period_s)
        sos = band_sos(self.cfg.band_hz, self.cfg.box_lowpass_hz, period_s)[1]       # the model's side: L B
        h = round(self.cfg.horizon_ms / 1000.0 / period_s)
        rows = []
        for m in self.cfg.modes:
            w = 2.0 * math.pi * m.hz
            _, resp = signal.sosfreqz(sos, worN=[m.hz], fs=1.0 / period_s)
            # o = c e + s (e - e_last) / dt must carry e_k at f_k as the mode does h later, undoing L B:
            # c + s D = exp((i - zeta) w h) / F(w), D the backward difference's response at w (it lags half a cycle)
            g = np.exp((1j - m.damping) * w * h * period_s) / resp[0]
            d = (1.0 - np.exp(-1j * w * period_s)) / period_s
            s = g.imag / d.imag
            rows.append([*m.direction, g.real - s * d.real, s])
        step = period_s / (self.cfg.ramp_ms / 1000.0)
        lead = round(self.cfg.joints_lead_ms / 1000.0 / period_s)
        for key, cycles in (("horizon_ms", h), ("joints_lead_ms", lead)):
            if cycles >= H_MAX:
                raise ValueError(f"dynamics.observer.{key} is {cycles} cycles of {1000 * period_s:g} ms; the delay "
                                 f"lines hold {H_MAX - 1}")
        settle = round(self.cfg.settle_ms / 1000.0 / period_s)
        return np.array([len(rows), h, step, lead, *np.ravel(f), *np.ravel(rows), settle])

    def terms(self, ctx: DynamicsContext) -> list[TwistTerm]:
        self.fed.append(TwistTerm(observer_law, self.params(ctx.period_s), [0.0] * STATE_SIZE))
        return [self.fed[-1]]

    @staticmethod
    def measured(term: TwistTerm) -> np.ndarray:
        """The last cycle's m = (B / s^2) a - L B FK(q) (3,), the arm's deflection in the band, from the term's state."""
        return term.state[MEASURED:MEASURED + 3]

    @staticmethod
    def settled(term: TwistTerm) -> bool:
        """The observer's term runs and its band has settled since its start (``settle_ms``)."""
        return term.state[7] != 0.0 and term.state[SETTLED] > term.params[-1]

    def with_frequencies(self, hz) -> Observer:
        """This observer with the modes at ``hz`` (one each; the follower's, `stiffness.dynamics.follower`)."""
        modes = [m.model_copy(update={"hz": float(f)}) for m, f in zip(self.cfg.modes, hz)]
        return Observer(self.cfg.model_copy(update={"modes": modes}))

    def follower(self, period_s: float, apply):
        """The follower of these modes (None unless ``follow``): a `stiffness.dynamics.follower.Follower`
        whose ``apply(hz)`` rewrites the running terms."""
        if not self.cfg.follow:
            return None
        h = round(self.cfg.horizon_ms / 1000.0 / period_s)
        lb = band_sos(self.cfg.band_hz, self.cfg.box_lowpass_hz, period_s)[1]
        return Follower(self.cfg.modes, lb, h, period_s, self.cfg.follow_range, self.cfg.follow_window_ms / 1000.0,
                        apply)

    def feed_motion(self, acceleration, ok: bool, p_tcp, sample_period_s: float = 0.0) -> None:
        """This cycle's acceleration (base, m/s^2), whether the accelerometer's samples arrive, and the nominal
        TCP of the joints the PLC reported (m, base), into the term's state; values that come less often than
        every `MAX_SAMPLE_MS` count as not arriving (the force-only path; `too_slow` says so)."""
        self.too_slow = math.isfinite(sample_period_s) and sample_period_s > MAX_SAMPLE_MS / 1000.0
        ok = ok and math.isfinite(sample_period_s) and not self.too_slow      # (infinite: not two values yet)
        for term in self.fed:
            s = term.state
            s[0], s[1], s[2] = acceleration
            s[3], s[4], s[5] = p_tcp
            s[6] = 1.0 if ok else 0.0

    def describe(self) -> str:
        modes = ", ".join(f"{m.hz:g} Hz" for m in self.cfg.modes)
        lo, hi = self.cfg.band_hz
        return f"observer ({modes}; band {lo:g}-{hi:g} Hz, horizon {self.cfg.horizon_ms:g} ms)"
