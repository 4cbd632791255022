"""The verdicts of the I/O process's health endpoints: is the task alive, healthy, ready to be relied on?

`HealthMonitor` is fed the to_plc values by register name (the same block the PLC reads) with the
time they were read, and keeps a window of the last ``window_s`` seconds. `verdicts` answers the JSON
of each probe (`io_process.endpoints.PROBES`), which `stiffcomp health` and orchestrators read::

    /health        {"healthy": false, "reason": "fault word 0x0001: sensor_timeout", "task_state": 1,
                    "fault_word": 1, "faults": ["sensor_timeout"], "exceed_rate": 0.002,
                    "cycles_per_s": 1000.0, "payload_active": 3}
    /health/live   {"live": true, "reason": "the cycle count rose 0.1 s ago, 998 cycles/s", ...}
    /health/ready  {"ready": false, "reason": "no PLC heartbeat seen yet: ...", "checks": {"plc": false, ...}}

Each verdict is the conjunction of checks taken in this order, the first failing one giving the reason:

========== ==================================================================== ====== ======= =====
check      passes when                                                          live   health  ready
========== ==================================================================== ====== ======= =====
image      the process image has been read at least once                        yes    yes     yes
running    the task state is RUN                                                        yes     yes
rising     the cycle count rose within ``stall_s``                              yes    yes     yes
no_fault   the fault word is 0                                                          yes     yes
deadlines  at most ``max_exceed_rate`` of the cycles in the window exceeded              yes     yes
sensor     status bit sensor_ok: a sample was seen and no sensor fault latched                  yes
plc        status bit plc_seen: the PLC's heartbeat has changed since the start                 yes
========== ==================================================================== ====== ======= =====

So ready implies healthy implies live. *Live* is what a restart could fix (the task stuck or dead; the
I/O process answers, or there is no verdict at all). *Healthy* is what /health answers: the task running
without a fault, its deadlines within the bound. *Ready* adds what the PLC relies on: a fresh sensor (the cycle's sensor
timeout, ``faults.sensor_timeout_ms``, clears sensor_ok) and a PLC whose heartbeat the cycle has seen
(supervised against ``faults.plc_heartbeat_timeout_ms`` while it enables, a lapse latching the fault
plc_heartbeat). Readiness is read from the status and fault words the cycle publishes, so it is the
same whether it is asked over HTTP or read from the Modbus block. Pure: no clock, no sockets; the
caller serves each verdict with HTTP 200 when it passes and 503 when not.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping

from plc_link.contract import FAULT_BITS, Status, TaskState

TASK_RUN = int(TaskState.RUN)
LIVE_CHECKS = ("image", "rising")
HEALTH_CHECKS = ("image", "running", "rising", "no_fault", "deadlines")
READY_CHECKS = (*HEALTH_CHECKS, "sensor", "plc")


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
        return self.verdicts(t)["health"]

    def verdicts(self, t: float) -> dict[str, dict]:
        """Every probe's JSON at time ``t`` (s): ``{"live": {...}, "health": {...}, "ready": {...}}``."""
        v = self._values
        word = int(v.get("fault_word", 0))
        faults = [self.fault_names.get(b, f"bit {b}") for b in range(16) if word >> b & 1]
        rate, cps = self._rates()
        out = {"task_state": int(v.get("task_state", -1)), "fault_word": word, "faults": faults,
               "exceed_rate": rate, "cycles_per_s": cps}
        if "payload_active" in v:               # the payload set in use, where the map binds it
            out["payload_active"] = int(v["payload_active"])
        checks = self._checks(t, out, rate)
        ok = {name: passed for name, (passed, _) in checks.items()}
        window = "" if rate is None else f", {100 * rate:.1f} % of cycles exceeded in the last {self.window_s:g} s"

        def first_failure(names: tuple[str, ...]) -> str | None:
            return next((checks[n][1] for n in names if not ok[n]), None)

        live_why = first_failure(LIVE_CHECKS)
        live = {"live": live_why is None, "reason": live_why or (
            f"the cycle count rose {t - self._last_rise:.1f} s ago"
            + ("" if cps is None else f", {cps:.0f} cycles/s")),
            "task_state": out["task_state"], "cycle_count": int(self._samples[-1][1]) if self._samples else None,
            "cycles_per_s": cps}
        health_why = first_failure(HEALTH_CHECKS)
        health = {"healthy": health_why is None, "reason": health_why or "running, no fault" + window, **out}
        ready_why = first_failure(READY_CHECKS)
        status = {k: v[k] for k in ("status_word", "sample_age_ms") if k in v}
        ready = {"ready": ready_why is None,
                 "reason": ready_why or "running, no fault, sensor fresh, PLC heartbeat seen" + window,
                 "checks": {n: ok[n] for n in READY_CHECKS}, **out, **status}
        return {"live": live, "health": health, "ready": ready}

    def _checks(self, t: float, out: dict, rate: float | None) -> dict[str, tuple[bool, str]]:
        """name -> (passed, the reason when not)."""
        state, word, status = out["task_state"], out["fault_word"], int(self._values.get("status_word", 0))
        stalled = t - (self._last_rise if self._last_rise is not None else t)
        age = self._values.get("sample_age_ms")
        return {
            "image": (bool(self._samples), "no reading of the process image yet"),
            "running": (state == TASK_RUN, f"the task is not running (task state {state})"),
            "rising": (self._last_rise is not None and stalled <= self.stall_s,
                       f"the cycle count has not risen for {stalled:.1f} s"),
            "no_fault": (not word, f"fault word 0x{word:04X}: {', '.join(out['faults'])}"),
            "deadlines": (rate is None or rate <= self.max_exceed_rate,
                          (f"{100 * (rate or 0.0):.1f} % of cycles exceeded in the last {self.window_s:g} s "
                           f"(bound {100 * self.max_exceed_rate:g} %)")),
            "sensor": (bool(status & Status.SENSOR_OK),
                       "no fresh sensor sample (status bit sensor_ok clear"
                       + ("" if age is None else f", newest sample {age:.0f} ms old") + ")"),
            "plc": (bool(status & Status.PLC_SEEN),
                    "no PLC heartbeat seen yet: the PLC has not changed plc_heartbeat since the start"),
        }

    def _rates(self) -> tuple[float | None, float | None]:
        if len(self._samples) < 2:
            return None, None
        (t0, c0, e0), (t1, c1, e1) = self._samples[0], self._samples[-1]
        if c1 <= c0 or t1 <= t0:
            return None, 0.0
        return (e1 - e0) / (c1 - c0), (c1 - c0) / (t1 - t0)
