"""The screen of `stiffcomp status`: the service's values by register name, made into rich tables.

Pure: `StatusView.update` takes one reading (values by name and the time it was read) and keeps a
short rolling window, from which `render` derives the cycle rate, exec p50/p99 and the exceed rate.
The registers give only the last cycle's exec time, so the percentiles are over the sampled cycles.

Once a reading fails (`StatusView.failed`), every value is blanked (shown as —) until one succeeds
again: a view that kept the last values would show "task RUN, rate 1,000 /s" for a service that is
gone. `why_zero` says, from the status bits, why the correction is zero (enable off, a fault, ramping,
stopped, no sensor sample yet).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Mapping

import numpy as np
from rich.console import Group
from rich.table import Table
from rich.text import Text

from plc_link.contract import FAULT_BITS, Fault, Status, TaskState

# the bits and states as the contract names them (plc_link.contract)
STATUS_BITS = {f.bit_length() - 1: (f.name or "").lower().replace("_", " ") for f in Status}
FAULT_NAMES = {bit: kind for kind, bit in FAULT_BITS.items()}
TASK_STATES = {s.value: s.name for s in TaskState}
WRENCH = (("fx", "N"), ("fy", "N"), ("fz", "N"), ("mx", "Nm"), ("my", "Nm"), ("mz", "Nm"))
DEFLECTION = (("dx", "mm"), ("dy", "mm"), ("dz", "mm"), ("rx", "deg"), ("ry", "deg"), ("rz", "deg"))


BLANK = "—"


def why_zero(status_word: int, fault_word: int) -> str:
    """Why the correction is zero, in words, from the status and fault bits (the first reason that holds)."""
    if status_word & Status.STOPPED:
        return "the service has stopped"
    if fault_word or status_word & Status.FAULTED:
        return (f"fault latched ({', '.join(Fault.spell(fault_word)) or 'see fault_word'}): the correction "
                f"{'is ramping' if status_word & Status.RAMPING else 'has ramped'} to zero until the PLC resets "
                "(command bit 2)")
    if not status_word & Status.SENSOR_OK:
        return "no good sensor sample yet"
    if status_word & Status.RAMPING:
        return "ramping to zero: the PLC's enable bit went off, or the service is stopping"
    if not status_word & Status.ACTIVE:
        return "the PLC's enable bit (command_word bit 0) is off"
    return "active: the model asks for no correction at this load"


def bit_names(word: int, names: Mapping[int, str]) -> list[str]:
    """The names of the bits set in ``word``; unknown bits as ``bit N``."""
    return [names.get(b, f"bit {b}") for b in range(16) if word >> b & 1]


class StatusView:
    """A rolling window of readings and their rendering.

    Parameters
    ----------
    source : what is shown in the title, e.g. ``modbus 127.0.0.1:5020``
    window_s : the span of the cycle rate and exceed rate, s
    samples : exec-time samples kept for the percentiles
    payload_names : the payload sets' names by index (the config's ``gravity.payloads``), for the row
        that shows ``payload_active``
    """

    def __init__(self, source: str, window_s: float = 2.0, samples: int = 500,
                 payload_names: Mapping[int, str] | None = None):
        self.source = source
        self.payload_names = dict(payload_names or {})
        self.window_s = window_s
        self.counts: deque[tuple[float, float, float]] = deque()     # (t, cycle_count, exceed_count)
        self.exec_us: deque[float] = deque(maxlen=samples)
        self.values: dict[str, float] = {}
        self.error: str | None = None
        self._last_cycle: float | None = None

    def update(self, values: Mapping[str, float], t: float) -> None:
        """One reading of the to_plc block by name, read at monotonic time ``t`` (s)."""
        self.values, self.error = dict(values), None
        cycle = values.get("cycle_count", 0.0)
        if cycle != self._last_cycle:              # a new cycle: its exec time is a new sample
            self.exec_us.append(values.get("last_exec_us", 0.0))
            self._last_cycle = cycle
        if self.counts and cycle < self.counts[-1][1]:
            self.counts.clear()                    # the service started again
        self.counts.append((t, cycle, values.get("exceed_count", 0.0)))
        while len(self.counts) > 2 and t - self.counts[1][0] >= self.window_s:
            self.counts.popleft()

    def failed(self, message: str) -> None:
        """The last reading failed: every value is blanked until a reading succeeds (rates start afresh)."""
        self.error = message
        self.values = {}
        self.counts.clear()
        self.exec_us.clear()
        self._last_cycle = None

    def rates(self) -> tuple[float | None, float | None]:
        """(cycles per second, fraction of cycles exceeded) over the window; None until two readings."""
        if len(self.counts) < 2 or self.counts[-1][0] <= self.counts[0][0]:
            return None, None
        (t0, c0, e0), (t1, c1, e1) = self.counts[0], self.counts[-1]
        rate = (c1 - c0) / (t1 - t0)
        return rate, ((e1 - e0) / (c1 - c0) if c1 > c0 else 0.0)

    def render(self) -> Group:
        v = self.values
        title = Text(f"stiffcomp status  {self.source}", style="bold")
        if self.error:
            title.append(f"   {self.error}: every value blank", style="bold red")
        return Group(title, self._task_table(v), self._values_table(v))

    def _task_table(self, v: Mapping[str, float]) -> Table:
        t = Table(show_header=False, box=None, padding=(0, 2))
        t.add_column(style="cyan")
        t.add_column()
        if not v:                                  # no answer: nothing is known, nothing is shown
            for row in ("task", "cycles", "exec", "jitter", "exceeded", "status", "faults", "payload", "correction",
                        "reloads"):
                t.add_row(row, BLANK)
            return t
        rate, exceed_rate = self.rates()
        p50, p99 = (np.percentile(self.exec_us, [50, 99]) if self.exec_us else (np.nan, np.nan))
        fault = int(v.get("fault_word", 0))
        status = int(v.get("status_word", 0))
        faults = bit_names(fault, FAULT_NAMES)
        state = TASK_STATES.get(int(v.get("task_state", -1)), "?")
        t.add_row("task", Text(state, style="green" if state == "RUN" else "yellow"))
        t.add_row("cycles", f"{int(v.get('cycle_count', 0))}   "
                  + ("rate —" if rate is None else f"rate {rate:,.0f} /s"))
        t.add_row("exec", f"p50 {p50:.0f} us   p99 {p99:.0f} us   last {v.get('last_exec_us', 0):.0f} us   "
                  f"(of {len(self.exec_us)} sampled cycles)")
        t.add_row("jitter", f"{v.get('period_jitter_us', 0):.0f} us (last cycle)")
        t.add_row("exceeded", f"{int(v.get('exceed_count', 0))}"
                  + ("" if exceed_rate is None else f"   {100 * exceed_rate:.2f} % over {self.window_s:g} s"))
        t.add_row("status", ", ".join(bit_names(status, STATUS_BITS)) or BLANK)
        t.add_row("faults", Text(f"0x{fault:04X}  " + (", ".join(faults) or "none"),
                                 style="bold red" if fault else "green"))
        if "payload_active" in v:
            index = int(v["payload_active"])
            t.add_row("payload", f"{index}  {self.payload_names.get(index, '(no set of this index in the config)')}")
        zero = not any(v.get(f"correction_q{k}", 0.0) for k in range(1, 7))
        t.add_row("correction", Text(f"zero: {why_zero(status, fault)}", style="yellow") if zero
                  else Text("applied", style="green"))
        t.add_row("reloads", BLANK if "reload_count" not in v else
                  f"{int(v['reload_count'])} accepted since start (stiffcomp reload)")
        return t

    def _values_table(self, v: Mapping[str, float]) -> Table:
        t = Table(title="per joint / axis", title_justify="left")
        t.add_column("joint")
        t.add_column("correction deg", justify="right")
        t.add_column("wrench", justify="right")
        t.add_column("deflection", justify="right")
        for k in range(6):
            (w, wu), (d, du) = WRENCH[k], DEFLECTION[k]
            if not v:
                t.add_row(f"q{k + 1}", BLANK, f"{w} {BLANK}", f"{d} {BLANK}")
                continue
            t.add_row(f"q{k + 1}", f"{v.get(f'correction_q{k + 1}', 0.0):+.5f}",
                      f"{w} {v.get(f'wrench_{w}', 0.0):+9.2f} {wu:<2}",
                      f"{d} {v.get(f'deflection_{d}', 0.0):+.4f} {du}")
        return t
