"""The steady cycle: most cycles of a running service change nothing but the time and the sample, and the
compiled service runs those in one compiled call (`service.kernel.steady_cycle`, in the model's compiled module);
every other cycle runs the Python glue around the compiled signal path (`Cycle.advance`), the reference.

A cycle is steady when no reload is pending, no stop is requested or under way, no fault is held from
outside, the last cycle kept its deadline (no overrun counted), the source reported no problem, and, checked
by the compiled call against a mirror of the Python objects' state: the PLC's command word is the one of the
last cycle (no edge, no undefined bit), its joints are the same, its payload index is the one requested
before and no payload switch, refusal or new table is under way, a sample comes after the first one with no
tare waiting for it, and a supervised heartbeat has not timed out; and no part of the dynamic compensation
reads the PLC's values (the feedforward's plan, which the glue feeds). Otherwise the call changes nothing and
the glue runs the cycle; after each cycle of the glue the mirror is exported again (`SteadyCycle.export`).

A steady cycle does what the glue would do, with the same functions compiled: the PLC's block read from the
process image and the cycle's published into it (`plc_link.image`'s protocol: `read_newest`,
`open_buffer`, `close_buffer`, `note_timing`), the heartbeat's bookkeeping, the safe state, the status word,
the sample's age and the task's counters (`service.cycle_rules`), the signal path (the model's compiled `cycle`, as
the glue's compiled path calls it), and the block packed as the glue's compiled publish packs it
(`service.kernel.pack`). It then writes to the Python objects what changed (the mirror's counters), and a
correction that is not finite trips ``value_invalid`` as the glue does. `tests/service/test_steady.py` holds
the two to the same bytes, cycle by cycle, through every kind of event.

Imported only by a compiled service (it loads numba).
"""

from __future__ import annotations

from time import time_ns

import numpy as np

from plc_link.contract import COMMAND_BITS, SENSOR_FAULTS, Fault, FromPlc, Status, TaskValues

from . import cycle_rules
from .kernel import steady_cycle as ks
from .signals import SIGNAL_SLOTS

H = {name: k for k, name in enumerate(ks.HEAD)}
HEAD_SIZE = len(ks.HEAD)
_NONE = float("nan")             # None in the mirror (no heartbeat seen yet, no sample yet)

# the literals of the compiled code, against their owners (a cached compiled module keeps its literals)
assert [SIGNAL_SLOTS[n][0] for n in ("status_word", "fault_word", "correction", "tare_count", "sensor_samples",
                                     "sample_age_ms", "payload_active", "reload_count")] == [
    ks.SIG_STATUS, ks.SIG_WORD, ks.SIG_VECTORS, ks.SIG_TARES, ks.SIG_SAMPLES, ks.SIG_AGE, ks.SIG_PAYLOAD,
    ks.SIG_RELOADS]
assert [int(Status[n]) for n in ("RUNNING", "ACTIVE", "FAULTED", "RAMPING", "SENSOR_OK", "PLC_SEEN", "TARE_REFUSED")] == [
    cycle_rules.RUNNING, cycle_rules.ACTIVE, cycle_rules.FAULTED, cycle_rules.RAMPING, cycle_rules.SENSOR_OK, cycle_rules.PLC_SEEN, cycle_rules.TARE_REFUSED]
assert (int(Fault.VALUE_INVALID), int(SENSOR_FAULTS), COMMAND_BITS) == (ks.VALUE_INVALID, cycle_rules.SENSOR_FAULTS,
                                                                       ks.COMMAND_BITS)
assert TaskValues._fields == ("heartbeat", "task_state", "cycle_count", "exceed_count", "last_exec_us",
                              "cycle_time_us", "period_jitter_us", "cycle_exceeded")


def _float(v) -> float:
    return _NONE if v is None else float(v)


class SteadyCycle:
    """The steady cycles of one compiled `service.app.Service`.

    Parameters
    ----------
    service : Service
        Compiled, with its packers.
    values : service.value_vector.Values
        The service's values; their head is this cycle's.
    inputs, outputs : (rows, scales) each
        The PLC's block, decoded into the values' inputs, and the block for the PLC (`service.kernel.pack.table`).
    """

    def __init__(self, service, values, inputs: tuple[np.ndarray, np.ndarray], outputs: tuple[np.ndarray, np.ndarray]):
        assert HEAD_SIZE <= values.at["task"]
        self.service = service
        self.V = V = values.V
        self.store = v = memoryview(V).cast("B").cast("d")
        (in_rows, in_scales), (out_rows, out_scales) = inputs, outputs
        self.T = np.ascontiguousarray(np.concatenate([in_rows, out_rows]))
        at = values.at
        V[at["scales"]:at["scales"] + len(in_rows) + len(out_rows)] = np.concatenate([in_scales, out_scales])
        for part in ("task", "signals", "t", "inputs", "scales"):
            v[H[f"at_{part}"]] = at[part]
        v[H["n_in"]], v[H["n_out"]] = len(in_rows), len(out_rows)
        fields = FromPlc._fields
        v[H["in_command"]], v[H["in_heartbeat"]] = fields.index("command_word"), fields.index("plc_heartbeat")
        v[H["in_q1"]], v[H["in_payload"]] = fields.index("q1"), fields.index("payload_index")
        self._hb = at["inputs"] + fields.index("plc_heartbeat")
        for name, place in service.image.places().items():      # the process image's parts in its bytes
            v[H[name]] = place
        self.call: tuple | None = None  # the model's compiled steady entry and its arrays, while armed

    def export(self) -> None:
        """Mirror the Python objects' state after a cycle of the glue, and arm the steady cycle where every
        condition the compiled call cannot see holds (the compiled stages bound, a cycle run, the joints seen)."""
        s = self.service
        cyc = s.cycle
        sup, comp = cyc.supervisor, cyc.compensator
        k, p = comp.kernel, comp.payloads
        pk = comp.predictor.kernel
        ready = (k is not None and pk is not None and pk is comp._pk and bool(k.bound) and comp.t_prev is not None
                 and sup.overruns == 0 and sup._q_last is not None and not cyc.stopping and p.quiet
                 and not comp.feeds)            # the feedforward's plan is fed from the PLC's values by the glue
        v, h = self.store, H
        v[h["ready"]] = ready
        image = s.image
        self.call = (pk.mod.steady, pk.F, pk.I, k.S, self.V, self.T, image.bytes, image.in_work,
                     image._timing) if ready else None
        if not ready:
            return
        v[h["prev_command"]], v[h["prev_hb"]], v[h["hb_change_t"]] = (sup.prev_command, sup.prev_hb,
                                                                      sup.hb_change_t)
        v[h["plc_seen"]], v[h["hb_timeout"]], v[h["enable_on_start"]] = (sup.plc_seen, sup.hb_timeout,
                                                                         sup.enable_on_start)
        for i, x in enumerate(sup._q_last):
            v[h["q_last0"] + i] = x
        v[h["t_prev"]], v[h["t_first"]], v[h["samples"]] = comp.t_prev, comp.t_first, comp.samples
        v[h["sample_t"]], v[h["have_sample"]], v[h["tare_pending"]] = (_float(comp.sample_t), comp.have_sample,
                                                                       comp._tare_pending)
        v[h["tare_refused"]], v[h["tares"]] = comp.tare_refused, comp.tares
        v[h["payload_requested"]], v[h["payload_active"]] = p.requested, p.active.index
        v[h["reloads"]], v[h["word"]], v[h["cycle_time_us"]] = cyc.reloads, comp.faults.word, s.period * 1e6

    def run(self, t: float, reading) -> bool:
        """One steady cycle at ``t`` with this cycle's sample (or None); False when it is not steady (nothing
        changed: the glue runs it). The compiled call reads the PLC's block from the image and publishes the
        cycle's (`plc_link.image`'s protocol, compiled)."""
        entry, F, I, S, V, T, mem, work, ring = self.call
        s = self.service
        v, info, comp = self.store, s.info, s.cycle.compensator
        if reading is not None:
            x = comp.kernel.x_in
            x[0], x[1], x[2], x[3], x[4], x[5] = reading.wrench
        v[_NOW], v[_FRESH], v[_N], v[_EXCEED], v[_EXEC], v[_JITTER] = (
            t, reading is not None, info.cycle_count + 1, info.exceed_count, info.last_exec_s * 1e6,
            info.last_jitter_s * 1e6)
        code = entry(F, I, S, V, T, mem, work, ring, time_ns())
        if code & ks.STALE:
            s.image.stale_reads += 1
        if not code & ks.STEADY:
            return False
        comp.t_prev = t
        if reading is not None:
            comp.samples += 1
            comp.sample_t = t
        if code & ks.HEARTBEAT:
            s.cycle.supervisor.heartbeat_seen(t, int(V[self._hb]))
        comp.limiter.safe = code & 2 != 0
        comp.ramping = code & 4 != 0
        s._record = None
        if not code & 1:
            comp.trip_not_finite()
            v[_READY] = 0.0
            self.call = None
        if not code & ks.PACKED:        # a value beyond float32: struct says which, as in the glue's publish
            s.image.publish(s.record)
        return True

_NOW, _FRESH, _N, _EXCEED, _EXEC, _JITTER, _READY = (H[n] for n in ("now", "fresh", "n", "exceed_count", "exec_us",
                                                                    "jitter_us", "ready"))
