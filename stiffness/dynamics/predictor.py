"""The wrench predicted over the delay: the correction reaches the joints late, so it is computed for the
wrench the arm will feel then (the paper's open problem 2).

Equation (each of the six channels of the external wrench w0, base axes, about the base origin):

    w_p = P(s) w0,     P(s) = 1 + h s w_d^2 / (s + w_d)^2

the wrench plus h times its rate, the rate taken through a critically damped low-pass at w_d = 2 pi f_d
(YAML: bandwidth_hz, default 150 Hz) so that what is left of the tooth passing and the sensor's noise is
not differentiated without bound. Below f_d, P is 1 + h s, the first two terms of e^(s h): a lead of h (s).
Its gain never exceeds 1 + h w_d / 2 (at f_d) and returns to 1 above; P(0) = 1, so a steady wrench passes
unchanged. The default is high because the wrench has already passed the sensor's and the service's
low-pass (52 and 100 Hz in the HIL) and the structure's modes take what is left above them: in the HIL
with 8 ms of extra delay a rate through 40 Hz left a steady path error 5 % above the static compensator's,
through 150 Hz 10 % below it (docs/dynamics.md). Without the structure's modes, lower it.

h is the horizon (YAML: horizon_ms; by default the dynamics' delay_ms less the structure's own lag_ms,
`DynamicsContext.horizon_s`): the end-to-end delay from the force at the tool to the correction applied,
measured by the HIL (``delay_ms`` of `stiffcomp hil circle`) or at commissioning, less what the arm itself
lags the force (the structure's modes know it, `stiffness.dynamics.structure`). h < 0 delays instead.

Real-time term: a `WrenchTerm` whose law is `predictor_law` (the biquad of P per channel, bilinear at the
cycle's period, direct form II transposed), on the Python and the compiled path; its state starts in the
steady state of the first wrench.

Example: a ramp of 1000 N/s is predicted 8 ms ahead once the differentiator has settled.

>>> from stiffness.dynamics.base import DynamicsContext
>>> import numpy as np
>>> part = Predictor(Predictor.Config(horizon_ms=8.0))
>>> term = part.terms(DynamicsContext(period_s=0.001))[0]
>>> for k in range(400):
...     w = np.array([k * 1.0, 0, 0, 0, 0, 0])         # 1 N per ms
...     term.law(term.state, term.params, w, 0.001)
>>> print(f"{w[0] - 399.0:.2f} N ahead")
8.00 N ahead
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from pydantic import Field

from ..effects.terms import WrenchTerm
from ..files.yaml_schema import Strict
from .base import DynamicsContext, Stage, biquad


def predictor_law(s, p, w, dt):
    """w (6,) <- P(s) w in place; p = [b0, b1, b2, a1, a2]; s = [z0 (6), z1 (6), started]."""
    b0, b1, b2, a1, a2 = p[0], p[1], p[2], p[3], p[4]
    if s[12] == 0.0:                       # the steady state of the first wrench (P(0) = 1)
        for i in range(6):
            s[6 + i] = (b2 - a2) * w[i]
            s[i] = (b1 - a1) * w[i] + s[6 + i]
        s[12] = 1.0
    for i in range(6):
        x = w[i]
        y = b0 * x + s[i]
        s[i] = b1 * x - a1 * y + s[6 + i]
        s[6 + i] = b2 * x - a2 * y
        w[i] = y


class Predictor(Stage):
    """``dynamics.predictor``: the wrench h ahead (module docstring)."""

    name = "predictor"

    class Config(Strict):
        horizon_ms: float | None = Field(None, ge=-20.0, le=100.0)       # None: delay_ms - structure.lag_ms
        bandwidth_hz: float = Field(150.0, gt=0.0, le=450.0)

    def horizon_s(self, ctx: DynamicsContext) -> float:
        h = self.cfg.horizon_ms
        return ctx.horizon_s if h is None else h / 1000.0

    def coefficients(self, ctx: DynamicsContext) -> np.ndarray:
        """P's biquad [b0, b1, b2, a1, a2] at the cycle's period."""
        h, wd = self.horizon_s(ctx), 2.0 * math.pi * self.cfg.bandwidth_hz
        return biquad([1.0, 2.0 * wd + h * wd * wd, wd * wd], [1.0, 2.0 * wd, wd * wd], ctx.period_s)

    def terms(self, ctx: DynamicsContext) -> list[WrenchTerm]:
        return [WrenchTerm(predictor_law, self.coefficients(ctx), [0.0] * 13)]

    def context(self, ctx: DynamicsContext) -> DynamicsContext:
        return replace(ctx, predictor=self.coefficients(ctx), predictor_horizon_s=self.horizon_s(ctx))

    def describe(self) -> str:
        h = "delay - lag" if self.cfg.horizon_ms is None else f"{self.cfg.horizon_ms:g} ms"
        return f"predictor (horizon {h}, rate through {self.cfg.bandwidth_hz:g} Hz)"
