"""The trace file (`stiffness.data.trace_file`): round trips through CSV and Parquet, rotation at the size limit, and
bad files named by line (issue 29, item 1)."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from stiffness.data.trace_file import COLUMNS, INTEGER, TraceFile, check_path, read_trace
from stiffness.errors import DataError, OutputError


def _rows(values: np.ndarray) -> np.ndarray:
    rows = values.copy()
    rows[:, 0] = np.arange(len(rows)) * 0.001                         # time in order
    rows[:, COLUMNS.index("cycle")] = np.arange(len(rows)) + 1         # one run: the count rises
    for k, c in enumerate(COLUMNS):
        if c in INTEGER:
            rows[:, k] = np.round(rows[:, k])
    return rows


@settings(max_examples=10, deadline=None)
@given(values=arrays(np.float64, st.tuples(st.integers(1, 40), st.just(len(COLUMNS))),
                     elements=st.floats(-1e6, 1e6, allow_nan=False)),
       suffix=st.sampled_from([".csv", ".parquet"]))
def test_what_is_written_is_read_back_exactly(tmp_path_factory, values, suffix):
    rows = _rows(values)
    path = tmp_path_factory.mktemp("trace") / f"t{suffix}"
    with TraceFile(path) as f:
        f.write(rows[: len(rows) // 2])
        f.write(rows[len(rows) // 2:])
    np.testing.assert_array_equal(read_trace(path).table, rows)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_the_trace_rotates_at_its_limit_and_keeps_what_it_says(tmp_path, caplog, suffix):
    """Rows go to NAME, the full file to NAME.1, older ones up to NAME.keep; beyond, the oldest goes with a
    warning. What the files hold is exactly the newest rows, in order."""
    rows = _rows(np.random.default_rng(0).normal(size=(2000, len(COLUMNS))))
    path = tmp_path / f"t{suffix}"
    with caplog.at_level(logging.WARNING, "stiffcomp.trace"), TraceFile(path, max_bytes=20_000, keep=2) as f:
        for k in range(0, len(rows), 100):
            f.write(rows[k: k + 100])
    assert f.rotations >= 3
    files = [tmp_path / f"t.{k}{suffix}" for k in (2, 1)] + [path]
    assert all(p.exists() for p in files) and not (tmp_path / f"t.3{suffix}").exists()
    kept = np.concatenate([read_trace(p).table for p in files])
    np.testing.assert_array_equal(kept, rows[-len(kept):])
    assert sum("removed, the oldest of 2 rotated files" in r.message for r in caplog.records) == f.rotations - 2


@pytest.mark.parametrize("name, match", [("t.txt", "suffix must be .csv or .parquet"),
                                         ("missing/t.csv", "does not exist")])
def test_a_trace_that_cannot_be_written_is_refused_by_name(tmp_path, name, match):
    with pytest.raises(OutputError, match=match):
        check_path(tmp_path / name)


@pytest.mark.parametrize("text, match", [
    ("time_s,cycle\n0,1\n", r"line 1: not a stiffcomp trace: column\(s\) unix_time_s"),
    (",".join(COLUMNS) + "\n" + ",".join(["0"] * len(COLUMNS)) + "\n" + ",".join(["x"] * len(COLUMNS)) + "\n",
     "line 3: not"),
    (",".join(COLUMNS) + "\n", "holds no cycle"),
    (",".join(COLUMNS) + "\n" + ",".join(["1"] * len(COLUMNS)) + "\n" + ",".join(["0"] * len(COLUMNS)) + "\n",
     "line 3: time_s goes back"),
])
def test_a_bad_trace_is_refused_naming_the_line(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DataError, match=match):
        read_trace(path)
