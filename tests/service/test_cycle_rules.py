"""The glue's formulas (`service.cycle_rules`) are one implementation: the Python glue runs them as they are, the steady
cycle runs them compiled (`service.kernel.steady_cycle`), and both give the same results over wide inputs. Each
formula is also held to what it means (the contract's status bits, the heartbeat's timeout)."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from plc_link.contract import SENSOR_FAULTS, Status, TaskValues
from service import cycle_rules
from service.kernel import steady_cycle as ks

times = st.floats(-1e6, 1e6, allow_nan=False)
maybe_nan = st.one_of(st.just(math.nan), times)
words = st.integers(0, 0xFFFF)


def same(a, b) -> bool:
    """Equal, NaN equal to NaN."""
    if isinstance(a, tuple):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b)) or a == b


@settings(max_examples=300, deadline=None)
@given(maybe_nan, times, st.booleans(), st.integers(0, 0xFFFF).map(float), times, st.booleans())
def test_the_heartbeat_compiled_is_the_heartbeat_in_python(prev, change_t, seen, hb, t, rose):
    py = cycle_rules.heartbeat(prev, change_t, seen, hb, t, rose)
    assert same(py, tuple(ks.heartbeat(prev, change_t, seen, hb, t, rose)))
    new_prev, new_change_t, new_seen = py
    assert new_prev == hb                               # the last value is kept
    changed = math.isnan(prev) or hb != prev
    assert new_change_t == (t if changed or rose else change_t)     # a change or the enable restarts the timeout
    assert new_seen == (seen or (changed and not math.isnan(prev)))  # seen once it changed after a first value


@settings(max_examples=300, deadline=None)
@given(st.floats(0, 10), st.booleans(), times, times)
def test_the_heartbeat_timeout_compiled_is_the_timeout_in_python(timeout, enabled, t, change_t):
    late = cycle_rules.heartbeat_late(timeout, enabled, t, change_t)
    assert late == ks.heartbeat_late(timeout, enabled, t, change_t)
    assert late == (timeout > 0 and enabled and t - change_t > timeout)


@settings(max_examples=300, deadline=None)
@given(words, st.booleans(), st.booleans(), st.booleans(), st.booleans(), st.booleans())
def test_the_status_word_compiled_is_the_status_word_in_python(word, held, ramping, have, seen, refused):
    status = cycle_rules.status_word(word, held, ramping, have, seen, refused)
    assert status == ks.status_word(word, held, ramping, have, seen, refused)
    bits = Status(status)
    assert Status.RUNNING in bits
    assert (Status.ACTIVE in bits) == (not held)
    assert (Status.FAULTED in bits) == (word != 0)
    assert (Status.RAMPING in bits) == ramping
    assert (Status.SENSOR_OK in bits) == (have and not word & int(SENSOR_FAULTS))
    assert (Status.PLC_SEEN in bits) == seen
    assert (Status.TARE_REFUSED in bits) == refused


@settings(max_examples=200, deadline=None)
@given(words, st.booleans(), st.booleans())
def test_the_safe_state_compiled_is_the_safe_state_in_python(word, hold, have):
    safe = cycle_rules.safe_state(word, hold, have)
    assert safe == ks.safe_state(word, hold, have)
    assert safe == (word != 0 or hold or not have)


@settings(max_examples=300, deadline=None)
@given(times, maybe_nan, maybe_nan)
def test_the_sample_age_compiled_is_the_age_in_python(now, sample_t, t_first):
    age = cycle_rules.sample_age_ms(now, sample_t, t_first)
    assert same(age, ks.sample_age_ms(now, sample_t, t_first))
    since = t_first if math.isnan(sample_t) else sample_t
    assert age == (0.0 if math.isnan(since) else (now - since) * 1000.0)


@settings(max_examples=200, deadline=None)
@given(st.integers(0, 2**40), st.integers(0, 4), st.integers(0, 2**31), st.floats(0, 1e6), st.floats(0, 1e6),
       st.floats(0, 1e6), st.booleans())
def test_the_task_row_compiled_is_the_row_in_python(n, state, exceeded_n, exec_us, cycle_us, jitter_us, exceeded):
    py = memoryview(np.zeros(len(TaskValues._fields))).cast("B").cast("d")    # as the service's values hold it
    compiled = np.zeros(len(TaskValues._fields))
    cycle_rules.task_row(py, n, state, exceeded_n, exec_us, cycle_us, jitter_us, exceeded)
    ks.task_row(compiled, n, state, exceeded_n, exec_us, cycle_us, jitter_us, exceeded)
    assert py.tolist() == compiled.tolist()
    row = TaskValues._make(py.tolist())
    assert row.heartbeat == n % 65536 and row.cycle_count == n and row.task_state == state
    assert row.exceed_count == exceeded_n and row.cycle_exceeded == exceeded
