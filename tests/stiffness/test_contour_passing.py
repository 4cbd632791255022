"""Where a cut's path passes a point (`TracedCut.passing`), computed once per point and read by the part reader
and the probe's checks alike: the fractional row abeam of it, the passes that came as close, and the trace's
blind spans the path passed near there."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from stiffness.data.trace_file import COLUMNS, Trace
from stiffness.part.contour import PASS_MARGIN_MM, TracedCut
from stiffness.part.left_out import GAP_MARGIN_MM

STEP_M = 1e-3        # the path's samples 1 mm apart along x, the tool axis z
R_M = 4e-3           # the tool radius


def _cut(c: np.ndarray, cycles: np.ndarray) -> TracedCut:
    """The cut of a trace whose tool centre went through ``c`` (m) at rows with cycle counts ``cycles``."""
    table = np.zeros((len(c), len(COLUMNS)))
    table[:, COLUMNS.index("cycle")] = cycles
    table[:, COLUMNS.index("time_s")] = 0.004 * cycles
    rows = np.arange(len(c))
    return TracedCut(c, np.array([0.0, 0.0, 1.0]), trace=Trace("cut.csv", table), tool=c, run=np.ones(len(c), bool),
                     rows=rows, q_deg=np.zeros(6))


def _line(n: int) -> np.ndarray:
    return np.column_stack([STEP_M * np.arange(n), np.zeros(n), np.zeros(n)])


@given(k=st.integers(2, 45), s=st.floats(0.0, 0.99), off_mm=st.floats(-2.0, 2.0), side=st.sampled_from([-1.0, 1.0]))
def test_a_point_on_the_wall_is_placed_at_the_fractional_row_abeam_of_it(k, s, off_mm, side):
    """A point the tool radius (within the tolerance) off a straight path, abeam of row k + s: one pass, u = k + s,
    beside no blind span. A point off the wall gets no row."""
    cut = _cut(_line(50), np.arange(50))
    x = STEP_M * (k + s)
    p = np.array([[x, side * (R_M + off_mm / 1000.0), 0.0], [x, side * (R_M + 9e-3), 0.0]])
    got = cut.passing(cut.in_plane(p), R_M, 3e-3)
    assert got.passes[0] == 1 and abs(got.u[0] - (k + s)) * STEP_M < 1e-9 and got.blind[0] == -1     # 1 nm
    assert got.passes[1] == 0 and np.isnan(got.u[1]) and got.blind[1] == -1
    assert got.row[0] in (k, k + 1) and abs(got.near[0] - np.hypot(x - STEP_M * got.row[0], p[0, 1])) < 1e-12


@given(k=st.integers(5, 44), lost=st.integers(1, 50))
def test_a_point_beside_rows_the_trace_lost_names_that_gap(k, lost):
    """The trace lost ``lost`` cycles after row 24: a point the path passed within GAP_MARGIN_MM (by its length)
    of that chord names the gap; farther along it names none."""
    cycles = np.arange(50)
    cycles[25:] += lost
    cut = _cut(_line(50), cycles)
    assert [b.row for b in cut.blind] == [24]
    got = cut.passing(cut.in_plane(np.array([[STEP_M * k, R_M, 0.0]])), R_M, 3e-3)
    near_gap = (k >= 24 - GAP_MARGIN_MM) and (k <= 25 + GAP_MARGIN_MM)
    assert got.blind[0] == (0 if near_gap else -1)


def test_a_point_two_passes_came_as_close_to_is_passed_twice():
    """Out along x and back 0.2 mm beside the way out (a closed contour's overlap): both passes come within
    PASS_MARGIN_MM as close to the point, so which made it cannot be told; beyond where the way back turned, one
    pass."""
    out = _line(30)
    back = out[::-1] + np.array([0.0, -0.2e-3, 0.0])
    c = np.vstack([out, back])
    cut = _cut(c, np.arange(len(c)))
    assert 0.2 < PASS_MARGIN_MM
    got = cut.passing(cut.in_plane(np.array([[0.0105, R_M, 0.0], [0.0, -0.05, 0.0]])), R_M, 3e-3)
    assert got.passes[0] == 2 and np.isnan(got.u[0])
    assert got.passes[1] == 0
