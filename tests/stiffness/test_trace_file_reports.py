"""The joints a trace holds between reports (`stiffness.data.trace_file.between_reports`): a robot that reports
every k rows moved between its reports, and a robot that stood still did not."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from stiffness.data.trace_file import between_reports


def held(q: np.ndarray, every: int, phase: int = 0) -> np.ndarray:
    """``q`` as a trace holds it when the joints come every ``every`` rows."""
    idx = np.maximum((np.arange(len(q)) - phase) // every * every + phase, 0)
    return q[idx]


@settings(max_examples=30, deadline=None)
@given(every=st.integers(2, 60), phase=st.integers(0, 10), w=st.floats(0.5, 3.0))
def test_a_smooth_motion_reported_every_k_rows_is_recovered_between_the_reports(every, phase, w):
    t = np.arange(4000) * 0.001
    q = np.column_stack([20.0 * np.sin(w * t + j) for j in range(6)])
    got = between_reports(t, held(q, every, phase))
    inner = slice(every + phase, len(t) - 2 * every)
    # within the reports: the motion itself, to far less than the step the staircase makes
    step = np.abs(np.diff(q, axis=0)).max() * every
    assert np.abs(got[inner] - q[inner]).max() <= 0.02 * step + 1e-9


def test_every_row_reported_is_left_as_it_is_and_a_pause_is_kept():
    t = np.arange(1000) * 0.001
    q = np.column_stack([np.sin(t + j) for j in range(6)])
    assert between_reports(t, q) is q
    # moves reported every 48 rows, a pause of 400 rows (no report: the robot stood still), moves again
    seg = np.repeat(np.arange(10.0), 48)[:, None] * np.ones(6)
    stand = np.full((400, 6), 9.0)
    q2 = np.vstack([seg, stand, 9.0 + seg])
    t2 = np.arange(len(q2)) * 0.001
    got = between_reports(t2, q2)
    assert np.all(got[480:880] == 9.0)                     # the pause held
    assert np.all(np.diff(got[:470, 0]) >= 0) and got[240, 0] > 4.5 and got[240, 0] < 5.5
