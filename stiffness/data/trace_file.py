"""The trace of a cut: what the service did in every cycle (docs/part_format.md, "The trace").

`stiffcomp run --trace FILE` (and `stiffcomp hil circle --trace FILE`) records one row per cycle:

=================================  ===============================================================
time_s, unix_time_s                the cycle's start: s since the task started; and wall-clock time
cycle                              the cycle count
q1_deg .. q6_deg                   the joint positions the PLC reported (what the encoders read: the
                                   commanded joints, correction included)
fx_N .. mz_Nm                      the wrench the cycle used: filtered, gravity and bias removed, in
                                   base axes, moment about the sensor origin
c1_deg .. c6_deg                   the joint correction the service sent (after limits)
acc_x_mps2 .. acc_z_mps2           the arm's acceleration at the tool, base axes, gravity and bias removed
                                   (0 without an accelerometer, or while its samples do not arrive; a
                                   trace written before it had none, and reads NaN there)
box_x_mps2 .. box_z_mps2           the accelerometer's reading last taken, as it came: box axes, gravity
                                   and bias in (0 without an accelerometer; NaN in an older trace)
status_word, fault_word, task_state  the contract's words (`plc_link.contract`)
box_samples                        the readings taken since start, mod 65536: one more in each cycle that
                                   took a new one (`Trace.box_readings`: the box's samples, to replay)
=================================  ===============================================================

The cycle counts 1, 2, ... with no gap; a gap is rows the service lost (its writer fell a ring behind):
`Trace.gaps` names each, and what reads the trace leaves out what happened then. A cycle that does not rise
is refused (two runs in one file).

The file is CSV or Parquet, by its suffix. `TraceFile` writes it in batches and rotates it: when the
file reaches ``max_bytes`` it becomes ``NAME.1.SUFFIX`` (the older ones move up to ``keep``; the oldest
goes, and the log says so) and a new ``NAME.SUFFIX`` starts. `read_trace` reads one file back.

Example: a round trip through CSV.

>>> import numpy as np, tempfile, pathlib
>>> rows = np.zeros((3, len(COLUMNS))); rows[:, 0] = [0.0, 0.001, 0.002]; rows[:, 2] = [1, 2, 3]
>>> path = pathlib.Path(tempfile.mkdtemp()) / "trace.csv"
>>> with TraceFile(path) as f:
...     f.write(rows)
>>> read_trace(path).cycle.tolist()
[1, 2, 3]
"""

from __future__ import annotations

import csv
import logging
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Self

import numpy as np

from ..errors import DataError, OutputError
from ..files.parquet import read_parquet

log = logging.getLogger("stiffcomp.trace")

Q = tuple(f"q{i}_deg" for i in range(1, 7))
WRENCH = ("fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm")
CORRECTION = tuple(f"c{i}_deg" for i in range(1, 7))
ACCELERATION = ("acc_x_mps2", "acc_y_mps2", "acc_z_mps2")
BOX = ("box_x_mps2", "box_y_mps2", "box_z_mps2")
WORDS = ("status_word", "fault_word", "task_state")
BOX_SAMPLES = "box_samples"
COLUMNS = ("time_s", "unix_time_s", "cycle", *Q, *WRENCH, *CORRECTION, *ACCELERATION, *BOX, *WORDS, BOX_SAMPLES)
OPTIONAL = {*ACCELERATION, *BOX, BOX_SAMPLES}     # a trace of an older service has none: NaN
INTEGER = {"cycle", *WORDS, BOX_SAMPLES}
SUFFIXES = (".csv", ".parquet")
DEFAULT_MAX_MB = 200.0
DEFAULT_KEEP = 4


def check_path(path: str | Path) -> Path:
    """The trace file ``path``, or OutputError naming what is wrong (suffix, folder, pyarrow)."""
    path = Path(path)
    if path.suffix.lower() not in SUFFIXES:
        raise OutputError(f"--trace {path}: the suffix must be .csv or .parquet (the file's format)")
    if not path.parent.is_dir():
        raise OutputError(f"--trace {path}: the folder {path.parent} does not exist")
    if path.suffix.lower() == ".parquet":
        try:
            import pyarrow  # noqa: F401
        except ImportError:
            raise OutputError(f"--trace {path}: writing Parquet needs pyarrow (pip install 'stiffcomp[parquet]'); "
                              "or name a .csv file") from None
    return path


class TraceFile:
    """Writes trace rows to ``path`` (CSV or Parquet by its suffix), rotating at ``max_bytes``.

    Parameters
    ----------
    path : the trace file
    max_bytes : rotate when the file reaches this size
    keep : rotated files kept beside the current one (NAME.1.SUFFIX is the newest)
    """

    def __init__(self, path: str | Path, max_bytes: float = DEFAULT_MAX_MB * 1e6, keep: int = DEFAULT_KEEP):
        self.path = check_path(path)
        self.max_bytes = float(max_bytes)
        self.keep = int(keep)
        self.parquet = self.path.suffix.lower() == ".parquet"
        self.rows = 0                 # written in all
        self.in_file = 0              # written to the current file
        self.rotations = 0
        self._open()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def _open(self) -> None:
        try:
            if self.parquet:
                import pyarrow as pa
                import pyarrow.parquet as pq

                self._schema = pa.schema([(c, pa.int64() if c in INTEGER else pa.float64()) for c in COLUMNS])
                self._writer = pq.ParquetWriter(self.path, self._schema)
            else:
                self._fh = open(self.path, "w", newline="")  # noqa: SIM115 - open across writes, closed by close()
                self._csv = csv.writer(self._fh)
                self._csv.writerow(COLUMNS)
        except OSError as e:
            raise OutputError(f"{self.path}: cannot write the trace: {e.strerror or e}") from e

    def write(self, rows: np.ndarray) -> None:
        """Append rows (k, len(COLUMNS)), in time order; a full file is rotated first, so the current file
        never ends empty."""
        if not len(rows):
            return
        if self.in_file and self.path.stat().st_size >= self.max_bytes:
            self._rotate()
        if self.parquet:
            import pyarrow as pa

            cols = [pa.array(rows[:, k].astype(np.int64) if c in INTEGER else rows[:, k]) for k, c in enumerate(COLUMNS)]
            self._writer.write_table(pa.Table.from_arrays(cols, schema=self._schema))
        else:
            self._csv.writerows(_csv_row(r) for r in rows)
            self._fh.flush()
        self.rows += len(rows)
        self.in_file += len(rows)

    def _rotate(self) -> None:
        self._close_current()
        stem, suffix = self.path.with_suffix(""), self.path.suffix
        oldest = Path(f"{stem}.{self.keep}{suffix}")
        if oldest.exists():
            oldest.unlink()
            log.warning("trace: %s removed, the oldest of %d rotated files (--trace-keep)", oldest, self.keep)
        for k in range(self.keep - 1, 0, -1):
            src = Path(f"{stem}.{k}{suffix}")
            if src.exists():
                src.rename(Path(f"{stem}.{k + 1}{suffix}"))
        if self.keep > 0:
            self.path.rename(Path(f"{stem}.1{suffix}"))
        self.rotations += 1
        self._open()
        self.in_file = 0

    def _close_current(self) -> None:
        if self.parquet:
            self._writer.close()
        else:
            self._fh.close()

    def close(self) -> None:
        self._close_current()


def _csv_row(r: np.ndarray) -> list[str]:
    return [str(int(v)) if c in INTEGER else repr(float(v)) for c, v in zip(COLUMNS, r)]


@dataclass(frozen=True)
class Gap:
    """Rows a trace lost: ``lost`` cycles between table rows ``row`` and ``row + 1``."""

    row: int
    after_cycle: int
    lost: int
    from_s: float                     # time_s of the rows either side
    to_s: float

    def text(self, source: str) -> str:
        return (f"{source}: {self.lost} row(s) lost: cycles {self.after_cycle + 1} to {self.after_cycle + self.lost} "
                f"(between t = {self.from_s:.3f} and {self.to_s:.3f} s)")

    def to_dict(self) -> dict:
        return {"kind": "rows_lost", "after_cycle": self.after_cycle, "lost_rows": self.lost, "from_s": self.from_s,
                "to_s": self.to_s}


REPORT_GAP = 2.5     # reports farther apart than this many typical spacings: the robot stood still between them
REPORT_MIN_S = 0.006  # reports closer than this (a PLC's 4 ms, RSI's) are read as they are: their corners are < 1 um


def between_reports(t: np.ndarray, q: np.ndarray) -> np.ndarray:
    """The joints ``q`` (rows at times ``t``) where they were reported less often than every row, interpolated
    between the reports.

    A row holds the joints last reported: a PLC every few cycles, a robot through the robot road every packet
    (ABB's EGM path corrections every 48 ms: 2.4 mm of a 50 mm/s feed). The robot moved between two reports,
    so a trace read as it is holds a staircase whose steps cut the corners of a contour (a path of 2.4 mm chords
    on a 31 mm radius lies up to 0.02 mm inside it; reports every 4 ms, a PLC's or RSI's, cut 0.2 mm chords whose
    corners lie 0.2 um inside, and their rows are read as they are, `REPORT_MIN_S`). Where the reports are further
    apart and the rows that bring new joints are at most 3 in 4 of the rows, the joints between two reports no
    farther apart than `REPORT_GAP` typical spacings are the cubic spline through the reports (scipy's
    CubicSpline: 1e-4 deg off a 20 deg, 0.5 Hz motion reported every 54 rows, where PCHIP is 0.06 deg off); a
    longer pause is a robot that stood still, and is kept."""
    changed = np.flatnonzero(np.r_[True, np.any(np.diff(q, axis=0) != 0.0, axis=1)])
    if len(changed) < 4 or len(changed) > 0.75 * len(q):
        return q
    from scipy.interpolate import CubicSpline

    spacing = np.diff(t[changed])
    typical = float(np.median(spacing))
    if typical < REPORT_MIN_S:
        return q
    breaks = np.flatnonzero(spacing > REPORT_GAP * typical)
    out = q.copy()
    for a, b in zip(np.r_[0, breaks + 1], np.r_[breaks, len(changed) - 1]):
        if b - a >= 1:
            k = changed[a:b + 1]
            out[k[0]:k[-1] + 1] = CubicSpline(t[k], q[k], axis=0)(t[k[0]:k[-1] + 1])
    return out


@dataclass
class Trace:
    """A trace read back: one array per column (``trace.time_s``, ``trace.q_deg`` ...)."""

    source: str
    table: np.ndarray                 # (N, len(COLUMNS)), the columns in COLUMNS' order

    def __len__(self) -> int:
        return len(self.table)

    def column(self, name: str) -> np.ndarray:
        return self.table[:, COLUMNS.index(name)]

    def block(self, names: tuple[str, ...]) -> np.ndarray:
        return self.table[:, [COLUMNS.index(n) for n in names]]

    time_s = property(lambda self: self.column("time_s"))
    cycle = property(lambda self: self.column("cycle").astype(np.int64))
    q_deg = property(lambda self: self.block(Q))

    @property
    def commanded_q_deg(self) -> np.ndarray:
        """The commanded joints of every row, where the robot moved between its reports (`between_reports`)."""
        return between_reports(self.time_s, self.q_deg)
    wrench_base = property(lambda self: self.block(WRENCH))
    correction_deg = property(lambda self: self.block(CORRECTION))
    fault_word = property(lambda self: self.column("fault_word").astype(np.int64))
    status_word = property(lambda self: self.column("status_word").astype(np.int64))

    def box_readings(self) -> tuple[np.ndarray, np.ndarray]:
        """The accelerometer's readings the service took, as they came: the time (``time_s``) of each cycle that
        took one and its reading (k, 3: box axes, m/s^2, gravity and bias in). Across rows the trace lost, the
        readings taken there are one, at the row after them. DataError, naming the trace, where it holds none."""
        n = self.column(BOX_SAMPLES)
        if not np.isfinite(n).all():
            raise DataError(f"{self.source}: no box_samples column: a trace written before the accelerometer's "
                            "readings were traced")
        new = np.flatnonzero(np.diff(n) != 0) + 1
        if not len(new):
            raise DataError(f"{self.source}: the accelerometer took no reading in this trace (box_samples never "
                            "changes: a service without accelerometer.enabled, or a box whose values never came)")
        return self.time_s[new], self.block(BOX)[new]

    def gaps(self) -> list[Gap]:
        """Where the cycle count jumps: the rows lost there (docs/part_format.md)."""
        c, t = self.cycle, self.time_s
        return [Gap(int(k), int(c[k]), int(c[k + 1] - c[k] - 1), float(t[k]), float(t[k + 1]))
                for k in np.nonzero(np.diff(c) > 1)[0]]


def looks_like_trace(path: str | Path) -> bool:
    """A trace by its suffix (Parquet: only traces and campaigns are) or its CSV header: the cycle count and
    the joints, as `COLUMNS` has them. False where the file cannot be read: its own reader says why."""
    path = Path(path)
    if path.suffix.lower() == ".parquet":
        return True
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            header = [h.strip() for h in next(csv.reader(fh), [])]
    except (OSError, csv.Error, UnicodeDecodeError):
        return False
    return "cycle" in header and Q[0] in header


def read_trace(path: str | Path) -> Trace:
    """Read a trace file (CSV or Parquet); DataError names the file, the line and the column."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: trace file not found")
    if path.suffix.lower() == ".parquet":
        t = read_parquet(path)
        missing = [c for c in COLUMNS if c not in t.column_names and c not in OPTIONAL]
        if missing:
            raise DataError(f"{path}: not a stiffcomp trace: column(s) {', '.join(missing)} missing")
        table = np.column_stack([t.column(c).to_numpy().astype(float) if c in t.column_names else
                                 np.full(t.num_rows, np.nan) for c in COLUMNS]) if t.num_rows else \
            np.zeros((0, len(COLUMNS)))
        return _checked(path, table, None)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = [h.strip() for h in next(reader, [])]
            missing = [c for c in COLUMNS if c not in header and c not in OPTIONAL]
            if missing:
                raise DataError(f"{path}: line 1: not a stiffcomp trace: column(s) {', '.join(missing)} missing")
            idx = [header.index(c) if c in header else None for c in COLUMNS]
            rows, lines = [], []
            for row in reader:
                if not row:
                    continue
                try:
                    rows.append([math.nan if k is None else float(row[k]) for k in idx])
                except (ValueError, IndexError):
                    raise DataError(f"{path}: line {reader.line_num}: not {len(header)} numbers") from None
                lines.append(reader.line_num)
    except (OSError, csv.Error, UnicodeDecodeError) as e:
        raise DataError(f"{path}: cannot read the trace: {e}") from e
    return _checked(path, np.array(rows, dtype=float).reshape(-1, len(COLUMNS)), np.array(lines))


def _checked(path: Path, table: np.ndarray, lines: np.ndarray | None) -> Trace:
    if not len(table):
        raise DataError(f"{path}: the trace holds no cycle")
    bad = ~np.isfinite(table[:, [COLUMNS.index(c) for c in ("time_s", "cycle", *Q)]]).all(axis=1)
    if bad.any():
        k = int(np.argmax(bad))
        where = f"line {lines[k]}" if lines is not None else f"row {k + 1}"
        raise DataError(f"{path}: {where}: a time, cycle or joint position is not finite")
    for col, what in ((0, "time_s goes back"), (2, "the cycle count does not rise")):
        back = np.diff(table[:, col]) < 0 if col == 0 else np.diff(table[:, col]) < 1
        if back.any():
            k = int(np.argmax(back)) + 1
            where = f"line {lines[k]}" if lines is not None else f"row {k + 1}"
            raise DataError(f"{path}: {where}: {what} (a trace is one run in time order; "
                            "give the rotated files one at a time)")
    return Trace(str(path), table)
