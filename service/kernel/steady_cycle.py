"""The compiled service's steady cycle (`service.steady`): whether a cycle is steady, and its bookkeeping, status
word, values and packed block around the model's `cycle` (the generated module's ``steady`` entry calls
`take_inputs`, `admit`, then `cycle`, then `publish`; numba, no allocation).

The formulas are not written here: the glue's (`service.cycle_rules`) and the process image's protocol
(`plc_link.image`) are compiled from the functions the Python glue and the image run. What is here is
the order, and the mirror: every place is read from the service's values ``V`` at run time, and `HEAD` names
the leading ones (the mirror of the Python objects' state, the cycle's inputs, and the places of the other
parts and of the image's). The Signals layout and the fault and command bits are literals here, checked
against their owners where `service.steady` is imported (a compiled module caches them, so they must not
come from another file). `admit`, `finish` and the two around them are compiled with the model's module,
whose key covers their files (`build.COMPILED_FILES`), not cached apart: numba's cache of a function does
not see a change in a function it calls.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from numba.extending import overload

from plc_link import image

from .. import cycle_rules
from . import pack

# the glue's formulas (`service.cycle_rules`), compiled here from the functions the Python glue runs
heartbeat, heartbeat_late, safe_state, status_word, sample_age_ms, task_row = (njit(f) for f in (
    cycle_rules.heartbeat, cycle_rules.heartbeat_late, cycle_rules.safe_state, cycle_rules.status_word, cycle_rules.sample_age_ms, cycle_rules.task_row))


@overload(image.copy_bytes)
def _copy_bytes(dst, src):
    """`image.copy_bytes` compiled: a loop, not a slice assignment (see there)."""
    def copy(dst, src):
        if len(dst) != len(src):
            raise ValueError("copy_bytes: the lengths differ")
        for i in range(len(dst)):
            dst[i] = src[i]
    return copy


# the process image's protocol on the cycle's side (`plc_link.image`), compiled from the image's functions
read_newest, open_buffer, close_buffer, note_timing = (njit(f) for f in (
    image.read_newest, image.open_buffer, image.close_buffer, image.note_timing))

HEAD = ("ready", "prev_command", "prev_hb", "hb_change_t", "plc_seen", "hb_timeout", "enable_on_start",
        "q_last0", "q_last1", "q_last2", "q_last3", "q_last4", "q_last5", "t_prev", "t_first", "samples",
        "sample_t", "have_sample", "tare_pending", "tare_refused", "tares", "payload_requested", "payload_active",
        "reloads", "word", "cycle_time_us", "now", "fresh", "n", "exceed_count", "exec_us", "jitter_us", "tmp",
        "at_task", "at_signals", "at_t", "at_inputs", "at_scales", "n_in", "n_out", "in_command", "in_heartbeat",
        "in_q1", "in_payload", "header_bytes", "in_off0", "in_off1", "in_bytes", "out_off0", "out_off1",
        "timing_count")
(READY, PREV_COMMAND, PREV_HB, HB_T, PLC_SEEN, HB_TIMEOUT, ENABLE_ON_START, Q_LAST, _, _, _, _, _, T_PREV, T_FIRST,
 SAMPLES, SAMPLE_T, HAVE, TARE_PENDING, TARE_REFUSED, TARES, PAYLOAD_REQUESTED, PAYLOAD_ACTIVE, RELOADS, WORD,
 CYCLE_TIME, NOW, FRESH, N, EXCEED, EXEC, JITTER, TMP, AT_TASK, AT_SIGNALS, AT_T, AT_INPUTS, AT_SCALES, N_IN, N_OUT,
 IN_COMMAND, IN_HEARTBEAT, IN_Q1, IN_PAYLOAD, HEADER_BYTES, IN_OFF0, IN_OFF1, IN_BYTES, OUT_OFF0, OUT_OFF1,
 TIMING_COUNT) = range(len(HEAD))

# Signals' places (`service.signals.SIGNAL_SLOTS`): the words, the five vectors, the counters
SIG_STATUS, SIG_WORD, SIG_VECTORS, SIG_TARES, SIG_SAMPLES, SIG_AGE, SIG_PAYLOAD, SIG_RELOADS = 0, 1, 2, 32, 33, 34, 35, 36
# `plc_link.contract.Fault.VALUE_INVALID` and `Command`'s defined bits (the status bits: `glue`)
VALUE_INVALID, COMMAND_BITS = 0x8, 0x7
# the signal path's flags (`template.cycle`) and what a steady call returns above its bits
FRESH_FLAG, GRAVITY_FLAG, SAFE_FLAG = 2, 4, 8
STEADY, HEARTBEAT, PACKED, STALE = 8, 16, 32, 64


@njit
def take_inputs(V, mem, work):
    """The PLC's newest complete block from the image (``mem``, its bytes) into the cycle's copy (``work``: the
    scratch, then the copy: `ProcessImage.in_work`); False when the writer kept overtaking (the last copy
    stays)."""
    n = int(V[IN_BYTES])
    h = mem[:int(V[HEADER_BYTES])].view(np.int64)
    return read_newest(h, 5, int(V[IN_OFF0]), int(V[IN_OFF1]), n, mem, work[:n], work[n:2 * n])


@njit
def publish(V, T, mem, ring, stamp_ns, bits, changed):
    """`finish` into the image's free to_plc buffer, published with ``stamp_ns`` and the cycle's timing into the
    timing ring (``ring``) when packed, closed unpublished when not (`ProcessImage.publish_with`)."""
    h = mem[:int(V[HEADER_BYTES])].view(np.int64)
    b = open_buffer(h, 0)
    code = finish(V, T, mem, int(V[OUT_OFF0]) if b == 0 else int(V[OUT_OFF1]), bits, changed)
    packed = code & PACKED != 0
    close_buffer(h, 0, b, stamp_ns, packed)
    if packed:
        at = int(V[TIMING_COUNT])
        note_timing(mem[at:at + 8].view(np.int64), ring, V[EXEC], V[JITTER])
    return code


@njit
def admit(V, T, IN):
    """Decode the PLC's block (IN) into V's inputs; (dt, the signal path's flags, whether the heartbeat changed)
    of a steady cycle, its bookkeeping done in the mirror; flags -1 (and the mirror as it was) when the cycle is
    not steady."""
    n_in, sc = int(V[N_IN]), int(V[AT_SCALES])
    pack.unpack(V, T[:n_in], V[sc:sc + n_in], V[TMP:TMP + 1], IN, 0)
    ai, t = int(V[AT_INPUTS]), V[NOW]
    command = int(V[ai + int(V[IN_COMMAND])])
    hb = float(int(V[ai + int(V[IN_HEARTBEAT])]))
    if V[READY] == 0.0 or command != V[PREV_COMMAND] or command & ~COMMAND_BITS:
        return 0.0, -1, False
    if int(V[ai + int(V[IN_PAYLOAD])]) != V[PAYLOAD_REQUESTED]:
        return 0.0, -1, False
    q = ai + int(V[IN_Q1])
    for i in range(6):
        if V[q + i] != V[Q_LAST + i]:
            return 0.0, -1, False
    prev = V[PREV_HB]
    prev_hb, change_t, seen = heartbeat(prev, V[HB_T], V[PLC_SEEN] != 0.0, hb, t, False)
    if heartbeat_late(V[HB_TIMEOUT], command & 1 != 0, t, change_t):
        return 0.0, -1, False               # the heartbeat fault trips: the glue's cycle
    fresh = V[FRESH] != 0.0
    if fresh and (V[HAVE] == 0.0 or V[TARE_PENDING] != 0.0):
        return 0.0, -1, False
    changed = hb != prev                    # (NaN: no heartbeat seen yet)
    V[PREV_HB], V[HB_T], V[PLC_SEEN] = prev_hb, change_t, 1.0 if seen else 0.0
    dt = t - V[T_PREV]
    V[T_PREV] = t
    if fresh:
        V[SAMPLES] += 1.0
        V[SAMPLE_T] = t
    enabled = command & 1 != 0 or V[ENABLE_ON_START] != 0.0
    safe = safe_state(int(V[WORD]), not enabled, V[HAVE] != 0.0)
    flags = (FRESH_FLAG | GRAVITY_FLAG if fresh else 0) | (SAFE_FLAG if safe else 0)
    return dt, flags, changed


@njit
def finish(V, T, mem, base, bits, changed):
    """The status word, Signals' counters and the task's into V, then the PLC's block packed into mem at base.
    Returns STEADY | the signal path's bits | HEARTBEAT when it changed | PACKED when the block is written."""
    word = int(V[WORD])
    if not bits & 1:
        word |= VALUE_INVALID           # what the glue's trip sets (`service.steady.SteadyCycle.run` trips it)
    status = status_word(word, bits & 2 != 0, bits & 4 != 0, V[HAVE] != 0.0, V[PLC_SEEN] != 0.0,
                              V[TARE_REFUSED] != 0.0)
    s = int(V[AT_SIGNALS])
    V[s + SIG_STATUS], V[s + SIG_WORD], V[s + SIG_TARES], V[s + SIG_SAMPLES] = status, word, V[TARES], V[SAMPLES]
    V[s + SIG_AGE] = sample_age_ms(V[T_PREV], V[SAMPLE_T], V[T_FIRST])
    V[s + SIG_PAYLOAD], V[s + SIG_RELOADS] = V[PAYLOAD_ACTIVE], int(V[RELOADS]) & 0xFFFF
    a = int(V[AT_TASK])                     # a steady cycle kept the last deadline; task_state 1: run
    task_row(V[a:a + 8], int(V[N]), 1, int(V[EXCEED]), V[EXEC], V[CYCLE_TIME], V[JITTER], False)
    V[int(V[AT_T])] = V[NOW]
    n_in, n_out, sc = int(V[N_IN]), int(V[N_OUT]), int(V[AT_SCALES])
    ok = pack.pack(V, T[n_in:n_in + n_out], V[sc + n_in:sc + n_in + n_out], V[TMP:TMP + 1], mem, base)
    return STEADY | bits | (HEARTBEAT if changed else 0) | (PACKED if ok else 0)
