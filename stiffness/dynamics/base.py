"""The interface of a part of the dynamic compensation (`stiffness.dynamics`): one file per part.

A part is what the service adds to its static prediction to follow the arm in time (docs/dynamics.md):
a predictor of the wrench over the delay, the structure's modes, the feedforward from the process plan.
Each is a class deriving `Stage` in its own module, with

* ``name``: its section in the service config's ``dynamics`` (and its key in `stiffness.dynamics.STAGES`);
* ``Config``: the schema of that section (a `Strict` model: its keys, units, bounds and defaults);
* ``terms(ctx)``: its per-cycle terms, of the real-time kinds (`stiffness.effects.terms`: a
  `WrenchTerm` before the springs, a `TwistTerm` on the deflection), each with its ``law`` written once at
  module level in the part's file, so the Python and the compiled cycle both run it;
* ``describe()``: one line for the start-up log.

Nothing else names a part: the service builds every part its config holds from the registry.
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import ClassVar

import numpy as np
from scipy import signal

from ..effects.terms import Term
from ..files.yaml_schema import Strict


@dataclass(frozen=True)
class DynamicsContext:
    """What every part may use: the cycle's period, the end-to-end delay and the structure's own lag (s), and
    once the predictor is built its biquad and horizon (the feedforward passes the plan through the same).

    ``horizon_s``: how far the wrench must be predicted so that the correction, applied ``delay_s`` after the
    force was measured, shows the deflection the arm has then; the structure itself lags the force by
    ``lag_s``, so that is ``delay_s - lag_s``."""

    period_s: float
    delay_s: float = 0.0
    lag_s: float = 0.0
    predictor: np.ndarray | None = None            # [b0, b1, b2, a1, a2] of the predictor, None: none
    predictor_horizon_s: float = 0.0

    @property
    def horizon_s(self) -> float:
        return self.delay_s - self.lag_s


class Stage(ABC):
    """Base of a part of the dynamic compensation, built from its config section."""

    name: ClassVar[str]
    Config: ClassVar[type[Strict]]

    def __init__(self, cfg: Strict):
        self.cfg = cfg

    @classmethod
    def from_config(cls, cfg: Strict, resolve=None) -> Stage:
        """The part of its validated section; ``resolve`` finds a path the section names (relative to the
        config file). A file it reads that is missing or bad raises `stiffness.errors.StiffnessError`."""
        return cls(cfg)

    @abstractmethod
    def terms(self, ctx: DynamicsContext) -> list[Term]:
        """The part's per-cycle terms for a cycle of ``ctx.period_s``."""

    def lag_s(self) -> float:
        """The lag of the arm's own response this part knows of (s; the structure's), else 0."""
        return 0.0

    def context(self, ctx: DynamicsContext) -> DynamicsContext:
        """The context the parts after this one see (the predictor adds its biquad and horizon)."""
        return ctx

    def plc_value(self) -> str | None:
        """The contract value (`plc_link.contract.FROM_PLC`) this part reads every cycle, or None."""
        return None

    def feed(self, t: float, value: float, p_tcp) -> None:
        """This cycle's `plc_value` (read at the cycle's time ``t``, s; the tool at ``p_tcp``, m) into the
        part's terms, before the cycle runs them."""

    reads_motion: ClassVar[bool] = False     # the part reads the accelerometer (`feed_motion`)

    def feed_motion(self, acceleration, ok: bool, p_tcp, sample_period_s: float = 0.0) -> None:
        """The arm's acceleration at the tool (base axes, m/s^2; `service.accelerometer`), whether its samples
        arrive, the nominal TCP of the joints the PLC reported (m, base) and the time between new values (s),
        into the part's terms."""

    def describe(self) -> str:
        return self.name


def biquad(b: list[float], a: list[float], period_s: float, prewarp_hz: float = 0.0) -> np.ndarray:
    """[b0, b1, b2, a1, a2] of the continuous transfer function b(s) / a(s) (second order at most) by the
    bilinear transform at ``period_s``, the frequency ``prewarp_hz`` mapped exactly (0: none)."""
    fs = 1.0 / period_s
    if prewarp_hz > 0.0:
        w = 2.0 * np.pi * prewarp_hz
        fs = w / (2.0 * np.tan(w / (2.0 * fs)))
    bz, az = signal.bilinear(b, a, fs)
    n = max(len(bz), len(az))               # both in powers of 1/z: a lower order leaves the last ones zero
    bz = np.concatenate([np.zeros(n - len(bz)), bz])
    bz, az = (np.concatenate([c, np.zeros(3 - len(c))]) for c in (bz, az))
    return np.array([bz[0], bz[1], bz[2], az[1], az[2]]) / az[0]
