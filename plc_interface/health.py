"""The verdict of the I/O process's ``GET /health``: is the task running, unfaulted, keeping its cycle?

`HealthMonitor` is fed the to_plc values by register name (the same block the PLC reads) with the
time they were read, and keeps a window of the last ``window_s`` seconds. `verdict` answers the JSON
that `stiffcomp health` and orchestrators read::

    {"healthy": false, "reason": "fault word 0x0001: sensor_timeout", "task_state": 1,
     "fault_word": 1, "faults": ["sensor_timeout"], "exceed_rate": 0.002, "cycles_per_s": 1000.0,
     "payload_active": 3}

Healthy means all of: the task state is RUN, the cycle count rose within ``stall_s``, the fault word
is 0, and the fraction of exceeded cycles in the window is at most ``max_exceed_rate``. Pure: no
clock, no sockets; the caller serves the verdict with HTTP 200 when healthy and 503 when not.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping

from .contract import FAULT_BITS

TASK_RUN = 1


class HealthMonitor:
    """Parameters
    ----------
    max_exceed_rate : monitoring.health_max_exceed_rate, the largest healthy fraction of exceeded cycles
    fault_bits : fault kind -> bit of the fault word (default: the contract's `FAULT_BITS`), to name the faults
    window_s : span of the exceed rate, s
    stall_s : a cycle count that has not risen for this long means the task is not running, s
    """

    def __init__(self, max_exceed_rate: float, fault_bits: Mapping[str, int] | None = None,
                 window_s: float = 10.0, stall_s: float = 1.0):
        self.max_exceed_rate = float(max_exceed_rate)
        self.fault_names = {b: n for n, b in (FAULT_BITS if fault_bits is None else fault_bits).items()}
        self.window_s, self.stall_s = float(window_s), float(stall_s)
        self._samples: deque[tuple[float, float, float]] = deque()   # (t, cycle_count, exceed_count)
        self._values: dict[str, float] = {}
        self._last_rise: float | None = None

    def update(self, t: float, values: Mapping[str, float]) -> None:
        """The to_plc values by name, read at monotonic time ``t`` (s)."""
        cycle, exceed = float(values.get("cycle_count", 0)), float(values.get("exceed_count", 0))
        if self._samples and cycle < self._samples[-1][1]:
            self._samples.clear()                        # the cycle process started again
        if not self._samples or cycle > self._samples[-1][1]:
            self._last_rise = t
        self._samples.append((t, cycle, exceed))
        while len(self._samples) > 2 and t - self._samples[1][0] >= self.window_s:
            self._samples.popleft()
        self._values = dict(values)

    def verdict(self, t: float) -> dict:
        """The /health JSON at time ``t`` (s), the same clock as `update`'s."""
        v = self._values
        word = int(v.get("fault_word", 0))
        faults = [self.fault_names.get(b, f"bit {b}") for b in range(16) if word >> b & 1]
        rate, cps = self._rates()
        out = {"task_state": int(v.get("task_state", -1)), "fault_word": word, "faults": faults,
               "exceed_rate": rate, "cycles_per_s": cps}
        if "payload_active" in v:               # the payload set in use, where the map binds it
            out["payload_active"] = int(v["payload_active"])
        if not self._samples:
            reason = "no reading of the process image yet"
        elif out["task_state"] != TASK_RUN:
            reason = f"the task is not running (task state {out['task_state']})"
        elif self._last_rise is None or t - self._last_rise > self.stall_s:
            reason = f"the cycle count has not risen for {t - (self._last_rise or t):.1f} s"
        elif word:
            reason = f"fault word 0x{word:04X}: {', '.join(faults)}"
        elif rate is not None and rate > self.max_exceed_rate:
            reason = (f"{100 * rate:.1f} % of cycles exceeded in the last {self.window_s:g} s "
                      f"(bound {100 * self.max_exceed_rate:g} %)")
        else:
            reason = "running, no fault" + ("" if rate is None else
                                            f", {100 * rate:.1f} % of cycles exceeded in the last {self.window_s:g} s")
            return {"healthy": True, "reason": reason, **out}
        return {"healthy": False, "reason": reason, **out}

    def _rates(self) -> tuple[float | None, float | None]:
        if len(self._samples) < 2:
            return None, None
        (t0, c0, e0), (t1, c1, e1) = self._samples[0], self._samples[-1]
        if c1 <= c0 or t1 <= t0:
            return None, 0.0
        return (e1 - e0) / (c1 - c0), (c1 - c0) / (t1 - t0)
