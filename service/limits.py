"""Limits on the joint correction: magnitude, rate, and the ramp to zero on a fault.

Each cycle the output moves toward its target by at most ``rate * dt`` per joint:

* running: target = clip(δq, ±max_correction), rate = max_rate;
* safe (faulted or not enabled): target = 0, rate = |output when the safe state began| / fault_ramp_s,
  so the correction reaches zero in fault_ramp_s and never jumps.
"""

from __future__ import annotations

from pydantic import Field, field_validator

from stiffness.files.yaml_schema import Strict


def _six_or_one(v: float | list[float]) -> list[float]:
    vals = [float(v)] * 6 if isinstance(v, (int, float)) else [float(x) for x in v]
    if len(vals) != 6:
        raise ValueError(f"needs one value or six (one per joint), got {len(vals)}")
    if any(not x > 0 for x in vals):
        raise ValueError("every value must be > 0")
    return vals


class LimitsConfig(Strict):
    """``limits``: the largest correction and its rate per joint (one value or six), the fault ramp."""

    max_correction_deg: float | list[float] = 0.5
    max_rate_deg_s: float | list[float] = 5.0
    fault_ramp_s: float = Field(0.2, gt=0.0, le=10.0)

    _check = field_validator("max_correction_deg", "max_rate_deg_s")(_six_or_one)


class CorrectionLimiter:
    """Rate- and magnitude-limited joint correction (deg), on six Python floats.

    Parameters
    ----------
    max_deg : (6,) largest |δq| per joint, deg
    max_rate_deg_s : (6,) largest rate of change per joint, deg/s
    ramp_s : float
        Time to ramp to zero on entering the safe state, s.
    max_dt_s : float
        Longest step taken into account, s (two cycle periods in the service): after a stall the
        output moves as after a normal cycle or two, not ``rate * stall``.
    """

    def __init__(self, max_deg, max_rate_deg_s, ramp_s: float, max_dt_s: float = float("inf")):
        self.max = [float(v) for v in max_deg]
        self.max_dt = float(max_dt_s)
        self.rate = [float(v) for v in max_rate_deg_s]
        self.ramp_s = float(ramp_s)
        self.out = [0.0] * 6
        self.safe = True
        self._ramp_rate = [0.0] * 6

    @classmethod
    def from_config(cls, section: LimitsConfig, period_s: float) -> CorrectionLimiter:
        """From the ``limits`` section; steps are capped at two periods of ``period_s`` (s)."""
        return cls(section.max_correction_deg, section.max_rate_deg_s, section.fault_ramp_s, 2.0 * period_s)

    def update(self, dt: float, target_deg, safe: bool) -> list[float]:
        """The output after one step of ``dt`` seconds toward ``target_deg`` (ignored when ``safe``)."""
        if safe:
            if not self.safe:
                self._ramp_rate = [abs(v) / self.ramp_s for v in self.out]
            target, rate = [0.0] * 6, self._ramp_rate
        else:
            target = [min(max(v, -m), m) for v, m in zip(target_deg, self.max)]
            rate = self.rate
        self.safe = safe
        dt = min(dt, self.max_dt)
        out = []
        for o, tg, r in zip(self.out, target, rate):
            step = r * dt
            d = tg - o
            out.append(tg if -step <= d <= step else (o + step if d > 0 else o - step))
        self.out = out
        return out

    @property
    def ramping(self) -> bool:
        return self.safe and any(v != 0.0 for v in self.out)
