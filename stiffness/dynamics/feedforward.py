"""Feedforward from the process plan: the correction starts ahead of a planned change of the force (an
entry, an exit), instead of after the sensor has seen it.

The plan gives the engagement e(tau) (0 outside the material, 1 at full engagement; an impact may exceed it) over the program's time tau, and the force at full
engagement F (N, at the tool, base axes): the planned wrench is W_p(tau) = e(tau) [F; p_tcp x F] (about
the base origin, as the service's w0). The service knows, each cycle at its time t,

    tau* = tau(t) + output_delay - lag        the time the correction computed now will stand for
    tau_m = tau* - h                          the time whose force the measured (and predicted) wrench shows

(output_delay: from the service's output to the joints, YAML output_delay_ms; lag: the structure's own,
h: the predictor's horizon, `stiffness.dynamics.base.DynamicsContext`) and adds the plan's change between
the two, passed through the same predictor P as the measured wrench:

    w <- w + W_p(tau*) - P(s) W_p(tau_m)

When the plan is right the planned part of the measured wrench is replaced by its value at tau*: an entry
or an exit is corrected on time, with no extrapolation; what the plan does not know (its force off, the
chip load's variation) stays measured. Outside a program (no plan) the term adds nothing.

Where the plan comes from (YAML source):

* ``file``: a CSV (`read_plan`: t_s, engagement, optionally fx_N, fy_N, fz_N; else YAML force_N), the
  program's time from the PLC's contract value ``plan_time_s`` (negative: no program running);
* ``plc``: the PLC writes ``plan_engagement``, the engagement its program plans ``lookahead_ms`` ahead, and
  the force is YAML force_N; the service keeps what it wrote over the last lookahead and reads e(tau*)
  and e(tau_m) there (a lookahead shorter than output_delay - lag cannot reach tau*: refused).

Real-time term: a `WrenchTerm` whose law is `feedforward_law` (P's biquad per channel, as the predictor's);
`Feedforward.feed` writes W_p(tau*) and W_p(tau_m) into its state each cycle, before the cycle's call.

Example: a plan that engages at 0.5 s, read 10 ms ahead.

>>> import numpy as np
>>> plan = Plan(np.array([0.0, 0.5, 0.6, 1.0]), np.array([0.0, 0.0, 1.0, 1.0]), np.array([[0.0, 500.0, 0.0]] * 4))
>>> [round(float(plan.engagement(t)), 2) for t in (0.45, 0.55, 0.7)]
[0.0, 0.5, 1.0]
"""

from __future__ import annotations

import bisect
from collections import deque
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from ..effects.terms import WrenchTerm
from ..files.yaml_schema import Strict
from .base import DynamicsContext, Stage
from .records import read_columns

COLUMNS = ("t_s", "engagement")
MAX_ENGAGEMENT = 10.0    # an impact may push the force beyond full engagement for a moment
FORCE = ("fx_N", "fy_N", "fz_N")


def feedforward_law(s, p, w, dt):
    """w (6,) += s[0:6] - M s[6:12] in place, M the biquads in p = [n, n x (b0, b1, b2, a1, a2)] in cascade
    (the predictor's, or none); s = [W_p(tau*) (6), W_p(tau_m) (6), n x (z0 (6), z1 (6)),
    started, the cascade's output (6)]."""
    n = int(p[0])
    done = 12 + 12 * n
    first = s[done] == 0.0
    for i in range(6):
        s[done + 1 + i] = s[6 + i]
    for k in range(n):
        o, z = 1 + 5 * k, 12 + 12 * k
        b0, b1, b2, a1, a2 = p[o], p[o + 1], p[o + 2], p[o + 3], p[o + 4]
        for i in range(6):
            x = s[done + 1 + i]
            if first:                       # each section in the steady state of the first input (gain 1)
                s[z + 6 + i] = (b2 - a2) * x
                s[z + i] = (b1 - a1) * x + s[z + 6 + i]
            y = b0 * x + s[z + i]
            s[z + i] = b1 * x - a1 * y + s[z + 6 + i]
            s[z + 6 + i] = b2 * x - a2 * y
            s[done + 1 + i] = y
    s[done] = 1.0
    for i in range(6):
        w[i] += s[i] - s[done + 1 + i]


@dataclass
class Plan:
    """A process plan: the engagement (0: none, 1: full) at program times ``t`` (s) and the force at full engagement
    (N, base axes, at the tool), one row per time."""

    t: np.ndarray
    e: np.ndarray
    force: np.ndarray

    def __post_init__(self):
        # the cycle reads the plan twice per cycle: plain lists, a bisection on them and the line between two
        # rows cost about 1 us; np.interp on a CSV's column (a strided view) copied all of it (90 us at 61k rows)
        self._t, self._e = [float(x) for x in self.t], [float(x) for x in self.e]
        self._f = [[float(x) for x in row] for row in np.asarray(self.force)]

    def _row(self, tau: float) -> int:
        """The last row at or before ``tau`` (the first one before the plan starts)."""
        return min(max(bisect.bisect_right(self._t, tau) - 1, 0), len(self._t) - 1)

    def engagement(self, tau: float) -> float:
        """e(tau), linear between the rows, held beyond the first and the last."""
        t, e = self._t, self._e
        k = self._row(tau)
        if tau <= t[0] or k == len(t) - 1:
            return e[k]
        return e[k] + (e[k + 1] - e[k]) * (tau - t[k]) / (t[k + 1] - t[k])

    def wrench(self, tau: float, p_tcp) -> list[float]:
        """W_p(tau) (6,): e F and its moment about the base origin, the tool at ``p_tcp`` (m)."""
        return planned(self.engagement(tau), self._f[self._row(tau)], p_tcp)


def planned(e: float, f, p_tcp) -> list[float]:
    """[e F; p_tcp x e F] (N, Nm): the planned wrench about the base origin."""
    fx, fy, fz = e * f[0], e * f[1], e * f[2]
    x, y, z = p_tcp[0], p_tcp[1], p_tcp[2]
    return [fx, fy, fz, y * fz - z * fy, z * fx - x * fz, x * fy - y * fx]


def read_plan(path: str | Path, force_N: list[float] | None = None) -> Plan:
    """The plan CSV (t_s, engagement in [0, MAX_ENGAGEMENT], optionally fx_N, fy_N, fz_N); DataError names the file and
    line; without force columns ``force_N`` is the force (ConfigError-free: the caller checks it is given)."""
    from ..errors import DataError

    cols = read_columns(path, COLUMNS, FORCE, "process plan")
    e = cols["engagement"]
    bad = np.nonzero((e < 0.0) | (e > MAX_ENGAGEMENT))[0]
    if len(bad):
        raise DataError(f"{path}: engagement = {e[bad[0]]:g} at t_s = {cols['t_s'][bad[0]]:g} is outside "
                        f"[0, {MAX_ENGAGEMENT:g}] (the force as a multiple of the force at full engagement)")
    if all(c in cols for c in FORCE):
        force = np.column_stack([cols[c] for c in FORCE])
    elif any(c in cols for c in FORCE):
        raise DataError(f"{path}: give all of {', '.join(FORCE)} or none (then dynamics.feedforward.force_N)")
    elif force_N is None:
        raise DataError(f"{path}: the plan has no force columns ({', '.join(FORCE)}) and "
                        "dynamics.feedforward.force_N is not set")
    else:
        force = np.tile(np.asarray(force_N, dtype=float), (len(e), 1))
    return Plan(cols["t_s"], e, force)


class Feedforward(Stage):
    """``dynamics.feedforward``: the plan's change added ahead of the measurement (module docstring)."""

    name = "feedforward"

    class Config(Strict):
        source: Literal["file", "plc"] = "file"
        file: str | None = None                                   # source file: the plan CSV
        force_N: list[float] | None = Field(None, min_length=3, max_length=3)
        lookahead_ms: float = Field(50.0, ge=0.0, le=1000.0)       # source plc
        output_delay_ms: float = Field(2.0, ge=0.0, le=100.0)

        @model_validator(mode="after")
        def _source(self):
            if self.source == "file" and self.file is None:
                raise ValueError("source file needs file: the plan CSV (t_s, engagement[, fx_N, fy_N, fz_N])")
            if self.source == "plc" and self.force_N is None:
                raise ValueError("source plc needs force_N: the force at full engagement, N, base axes")
            return self

    def __init__(self, cfg: Strict, plan: Plan | None = None):
        super().__init__(cfg)
        self.plan = plan                          # source file: read by the service (its paths)
        self.written: deque[tuple[float, float]] = deque()     # source plc: (t, e(t + lookahead))
        self.fed: deque[WrenchTerm] = deque(maxlen=2)          # a model reload's ramp runs two predictors
        self._seen: tuple[float, float] | None = None           # source file: (t, the PLC's time) when it changed
        self.lead_s = 0.0
        self.h = 0.0

    @classmethod
    def from_config(cls, cfg, resolve=None) -> Feedforward:
        if cfg.source != "file":
            return cls(cfg)
        return cls(cfg, read_plan(resolve(cfg.file) if resolve is not None else cfg.file, cfg.force_N))

    def terms(self, ctx: DynamicsContext) -> list[WrenchTerm]:
        sections = [ctx.predictor] if ctx.predictor is not None else []
        p = np.array([len(sections), *np.ravel(sections)])
        self.h = ctx.predictor_horizon_s
        self.lead_s = self.cfg.output_delay_ms / 1000.0 - ctx.lag_s
        if self.cfg.source == "plc" and self.cfg.lookahead_ms / 1000.0 < self.lead_s:
            raise ValueError(f"dynamics.feedforward.lookahead_ms = {self.cfg.lookahead_ms:g} cannot reach "
                             f"output_delay_ms - lag ({1000 * self.lead_s:g} ms)")
        self.fed.append(WrenchTerm(feedforward_law, p, [0.0] * (19 + 12 * len(sections))))
        return [self.fed[-1]]

    def plc_value(self) -> str:
        return "plan_time_s" if self.cfg.source == "file" else "plan_engagement"

    def feed(self, t: float, value: float, p_tcp) -> None:
        """The cycle at ``t`` (s): W_p(tau*) and W_p(tau_m) into the term's state, from the PLC's ``value``
        (source file: the program's time, s, negative: none; source plc: the engagement planned
        lookahead ahead) and the tool at ``p_tcp`` (m, base)."""
        if self.cfg.source == "file":
            if value < 0.0 or self.plan is None:
                now = then = [0.0] * 6
                self._seen = None
            else:
                if self._seen is None or value != self._seen[1]:     # the PLC wrote a new time: from now on
                    self._seen = (t, value)
                tau = value + (t - self._seen[0]) + self.lead_s       # its clock runs on between its writes
                now, then = self.plan.wrench(tau, p_tcp), self.plan.wrench(tau - self.h, p_tcp)
        else:
            ahead = self.cfg.lookahead_ms / 1000.0
            w = self.written
            w.append((t, float(value)))
            while len(w) > 2 and w[1][0] <= t - ahead - abs(self.h) - 0.05:
                w.popleft()
            f = self.cfg.force_N
            now = planned(self._at(t + self.lead_s - ahead), f, p_tcp)
            then = planned(self._at(t + self.lead_s - self.h - ahead), f, p_tcp)
        for term in self.fed:
            term.state[0:6] = now
            term.state[6:12] = then

    def _at(self, t_written: float) -> float:
        """The engagement the PLC wrote at ``t_written`` (the last one before it; the first one before that)."""
        w = self.written
        k = bisect.bisect_right(w, (t_written, float("inf"))) - 1
        return w[max(k, 0)][1]

    def describe(self) -> str:
        src = f"plan {self.cfg.file}" if self.cfg.source == "file" else f"PLC, {self.cfg.lookahead_ms:g} ms ahead"
        return f"feedforward ({src}, output delay {self.cfg.output_delay_ms:g} ms)"
