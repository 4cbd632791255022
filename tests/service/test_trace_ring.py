"""The trace ring between the cycle and the trace writer (`service.trace`, issue 29): rows come out as they
went in, in order; a writer that falls behind loses the oldest rows and counts every one; a trace that cannot
be written stops the service before anything starts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.testing import CONFIG
from service.app import Service
from service.config import load_config
from service.errors import TraceError
from service.signals import Signals
from service.trace import TraceOptions, TraceRing
from stiffness.data.trace_file import COLUMNS


@settings(max_examples=25, deadline=None)
@given(batches=st.lists(st.integers(0, 150), min_size=1, max_size=8))
def test_rows_come_out_in_order_and_what_overran_the_ring_is_counted(batches):
    """Property: after puts in batches (each taken or not), the rows taken are the put rows minus exactly the
    ones counted lost, which are the oldest of each overrun, in order."""
    ring = TraceRing(rows=64)
    try:
        got, n = [], 0
        for k, size in enumerate(batches):
            for _ in range(size):
                n += 1
                q = [float(n), 0.0, 0.0, 0.0, 0.0, float(-n)]
                zeros = [0.0] * 6
                sig = Signals(n & 0xFFFF, 0, [0.5 * n] * 6, zeros, [float(n)] * 6, zeros, zeros, 0, n, 0.0, 0, 0,
                              0.25 * n, 0.0, -0.5 * n, 9.75, -0.125 * n, 2.0, (3 * n) & 0xFFFF)
                ring.put_cycle(n * 0.001, q, sig, 1)
            if k % 2 == 0 or k == len(batches) - 1:
                got.append(ring.take())
        rows = np.concatenate(got) if got else np.zeros((0, len(COLUMNS)))
        c = ring.counts
        assert c["cycles"] == n and len(rows) + c["lost"] == n
        cycle = rows[:, COLUMNS.index("cycle")]
        assert np.all(np.diff(cycle) > 0) and (len(rows) == 0 or cycle[-1] == n)
        # each row is its own cycle's, whole: its time, joints, wrench, correction and words agree
        np.testing.assert_allclose(rows[:, COLUMNS.index("time_s")], cycle * 0.001)
        np.testing.assert_array_equal(rows[:, COLUMNS.index("q1_deg")], cycle)
        np.testing.assert_array_equal(rows[:, COLUMNS.index("fz_N")], cycle)
        np.testing.assert_array_equal(rows[:, COLUMNS.index("c6_deg")], 0.5 * cycle)
        np.testing.assert_array_equal(rows[:, COLUMNS.index("acc_x_mps2")], 0.25 * cycle)
        np.testing.assert_array_equal(rows[:, COLUMNS.index("acc_z_mps2")], -0.5 * cycle)
        np.testing.assert_array_equal(rows[:, COLUMNS.index("status_word")], cycle % 65536)
        np.testing.assert_array_equal(rows[:, COLUMNS.index("box_x_mps2")], 9.75)
        np.testing.assert_array_equal(rows[:, COLUMNS.index("box_y_mps2")], -0.125 * cycle)
        np.testing.assert_array_equal(rows[:, COLUMNS.index("box_samples")], (3 * cycle) % 65536)
    finally:
        ring.close()


@pytest.mark.parametrize("name", ["trace.txt", "nowhere/trace.csv"])
def test_a_trace_that_cannot_be_written_stops_the_service_before_it_opens_anything(tmp_path, name):
    cfg = load_config(CONFIG / "default.yaml")
    with pytest.raises(TraceError, match="--trace"):
        Service(cfg, TraceOptions(Path(tmp_path) / name))
