"""The glue's per-cycle formulas, written once: the Python glue (`service.supervision`, `service.pipeline`,
`service.app`) calls each as it is, and the steady cycle (`service.kernel.steady_cycle`) compiles the same functions
(numba) and runs them all in one compiled call, as the effects' laws are run by both paths. What a cycle
decides and reports is therefore computed by one function whichever way the cycle runs:

* `heartbeat` and `heartbeat_late`: the PLC heartbeat's bookkeeping and its timeout (the fault's message
  stays with the supervisor);
* `safe_state`: whether the correction must ramp to zero;
* `status_word`: the `plc_link.contract.Status` bits of the cycle;
* `sample_age_ms`: the age of the newest good sample;
* `task_row`: the task's counters of the cycle, in `plc_link.contract.TaskValues`' order.

None is NaN here (no heartbeat seen yet, no sample yet). Each function is plain numeric Python that numba
compiles (no objects, no lists). The bits are literals (a compiled module caches them); `service.steady` checks
them against their owners where it is imported.
"""

from __future__ import annotations

import math

# `plc_link.contract.Status`, and `SENSOR_FAULTS` of `Fault`
RUNNING, ACTIVE, FAULTED, RAMPING, SENSOR_OK, PLC_SEEN, TARE_REFUSED = 0x1, 0x2, 0x4, 0x8, 0x10, 0x20, 0x80
SENSOR_FAULTS = 0x1F


def heartbeat(prev: float, change_t: float, seen: bool, hb: float, t: float, enable_rose: bool):
    """The heartbeat ``hb`` read at ``t`` (s): (prev, change_t, seen) after it. A change restarts the
    timeout (change_t) and the first change says the PLC is there (seen); so does the enable's rising edge
    restart the timeout (supervision starts when the PLC enables). ``prev``: NaN before the first value."""
    if math.isnan(prev) or hb != prev:
        if not math.isnan(prev):
            seen = True
        prev = hb
        change_t = t
    if enable_rose:
        change_t = t
    return prev, change_t, seen


def heartbeat_late(timeout_s: float, enabled_by_plc: bool, t: float, change_t: float) -> bool:
    """Whether the heartbeat has not changed for longer than ``timeout_s`` while the PLC enables (0: off)."""
    return timeout_s > 0.0 and enabled_by_plc and t - change_t > timeout_s


def safe_state(fault_word: int, hold: bool, have_sample: bool) -> bool:
    """Whether the correction must ramp to zero: a fault latched, the PLC does not enable or the service stops
    (``hold``), or no sample has come yet."""
    return fault_word != 0 or hold or not have_sample


def status_word(fault_word: int, held: bool, ramping: bool, have_sample: bool, plc_seen: bool,
                tare_refused: bool) -> int:
    """The cycle's `Status` bits: running; active unless the limiter holds the safe state (``held``); faulted;
    ramping to zero; the sensor ok (a sample came and no sensor fault); the PLC seen; a tare refused."""
    return (RUNNING | (0 if held else ACTIVE) | (FAULTED if fault_word != 0 else 0) | (RAMPING if ramping else 0)
            | (SENSOR_OK if have_sample and fault_word & SENSOR_FAULTS == 0 else 0) | (PLC_SEEN if plc_seen else 0)
            | (TARE_REFUSED if tare_refused else 0))


def sample_age_ms(now: float, sample_t: float, t_first: float) -> float:
    """The age (ms) at ``now`` of the newest good sample (``sample_t``), or of the start (``t_first``) before
    the first; 0 before any cycle."""
    since = t_first if math.isnan(sample_t) else sample_t
    return 0.0 if math.isnan(since) else (now - since) * 1000.0


def task_row(out, cycle_count: int, state: int, exceed_count: int, exec_us: float, cycle_time_us: float,
             jitter_us: float, exceeded: bool) -> None:
    """The task's counters into ``out`` (8 floats, `TaskValues`' order; an array, or a memoryview of doubles in
    Python): the heartbeat (the count's low 16
    bits), the state, the count, the exceeded cycles, the last exec time, the cycle time, the last jitter and
    whether the last cycle exceeded."""
    out[0] = float(cycle_count & 0xFFFF)
    out[1] = float(state)
    out[2] = float(cycle_count)
    out[3] = float(exceed_count)
    out[4] = exec_us
    out[5] = cycle_time_us
    out[6] = jitter_us
    out[7] = 1.0 if exceeded else 0.0
