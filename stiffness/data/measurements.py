"""The measurement format: one row per measured body per reading (docs/measurement_format.md).

A reading is one load state at one configuration at one time: the joint angles, the wrench the sensor
measured (bias removed; force in N, moment about the sensor origin in Nm, sensor axes) and, for each
measured body, its deflection: loaded minus unloaded position in base axes (mm) and the rotation
vector log(R_loaded R_unloaded^T) in base axes (deg).

A campaign may measure any subset of the six deflection components: a laser tracker gives the TCP
position only. A component that was not measured is an absent column or an empty cell; in memory it
is NaN (``Dataset.measured`` is False there). A NaN or inf written in the file stays an error.

Measurement axes. A row may give its deflection in axes of its own instead of the base axes
(``Dataset.axes``, in memory only): a CMM or a probe measures a machined surface along its normal, so
a point of a part (`stiffness.part.rows`) is a TCP row whose first axis is the surface normal and whose
only measured component is that one. The model's predictions and the fit's design follow the row's
axes (`stiffness.data.campaign.Context`), so the same identification code fits campaigns and parts.
"""

from __future__ import annotations

import csv
import math
from array import array
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..errors import DataError, Problems, quote
from ..files.parquet import read_parquet
from ..kinematics.robot import BODIES, Robot

Q_COLS = tuple(f"q{i}_deg" for i in range(1, 7))
WRENCH_COLS = ("fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm")
DEFLECTION_COLS = ("dx_mm", "dy_mm", "dz_mm", "rx_deg", "ry_deg", "rz_deg")
COLUMNS = ("time_s", "config", *Q_COLS, *WRENCH_COLS, "body", *DEFLECTION_COLS)
REQUIRED_COLS = ("time_s", "config", *Q_COLS, *WRENCH_COLS, "body")
NUMERIC_COLS = ("time_s", *Q_COLS, *WRENCH_COLS, *DEFLECTION_COLS)
COMPONENTS = ("dx", "dy", "dz", "rx", "ry", "rz")


@dataclass
class Dataset:
    """A measurement campaign held as column arrays, one entry per row of the file.

    Attributes
    ----------
    time_s : (N,) seconds, in the order the readings were taken
    config : (N,) configuration labels
    q_deg : (N, 6) joint angles, deg
    wrench : (N, 6) sensor wrench [fx, fy, fz (N), mx, my, mz (Nm)] in sensor axes
    body : (N,) body index, 0..5 for A1..A6 and 6 for the TCP
    deflection : (N, 6) [dx, dy, dz (mm), rx, ry, rz (deg)] in base axes; NaN where not measured
    line : (N,) the file line (or parquet row + 2) each row came from
    axes : (N, 3, 3) or None
        Row n's deflection components in its own axes: row k of ``axes[n]`` is axis k in base axes
        (an orthonormal matrix), for both the position and the rotation components; None: base axes.
    """

    time_s: np.ndarray
    config: np.ndarray
    q_deg: np.ndarray
    wrench: np.ndarray
    body: np.ndarray
    deflection: np.ndarray
    line: np.ndarray | None = None
    source: str = "<memory>"
    ignored_columns: list[str] = field(default_factory=list)
    axes: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.time_s)
        self.config = np.asarray(self.config).astype(str)
        self.body = np.asarray(self.body, dtype=int)
        if self.line is None:
            self.line = np.arange(n) + 2
        for name in ("config", "q_deg", "wrench", "body", "deflection", "line"):
            if len(getattr(self, name)) != n:
                raise ValueError(f"Dataset.{name} has {len(getattr(self, name))} rows, expected {n}")
        if self.axes is not None:
            self.axes = np.asarray(self.axes, dtype=float)
            if self.axes.shape != (n, 3, 3):
                raise ValueError(f"Dataset.axes has shape {self.axes.shape}, expected ({n}, 3, 3)")
            if not np.allclose(self.axes @ np.swapaxes(self.axes, 1, 2), np.eye(3), atol=1e-9):
                raise ValueError("Dataset.axes must hold orthonormal matrices (one set of axes per row)")

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def measured(self) -> np.ndarray:
        """(N, 6) bool: which deflection components each row measured (False where NaN)."""
        return np.isfinite(self.deflection)

    def subset(self, mask: np.ndarray) -> Dataset:
        """The rows where ``mask`` (boolean or index array) selects."""
        return Dataset(
            self.time_s[mask], self.config[mask], self.q_deg[mask], self.wrench[mask], self.body[mask],
            self.deflection[mask], self.line[mask], self.source, list(self.ignored_columns),
            None if self.axes is None else self.axes[mask],
        )

    @property
    def configs(self) -> list[str]:
        """Configuration labels in order of first appearance."""
        _, first = np.unique(self.config, return_index=True)
        return [str(self.config[i]) for i in sorted(first)]

    def readings(self) -> tuple[np.ndarray, np.ndarray]:
        """Group rows into readings (same config, time, joint angles and wrench).

        Returns ``(first_row, reading_of_row)``: the index of one row per reading, and for each row
        the index of its reading.
        """
        key = np.concatenate(
            [np.unique(self.config, return_inverse=True)[1][:, None].astype(float),
             self.time_s[:, None], self.q_deg, self.wrench], axis=1)
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        return first, inverse.reshape(-1)

    def to_csv(self, path: str | Path) -> None:
        """Write the dataset in the measurement format.

        A component measured in no row is left out of the header; one measured in some rows only is
        an empty cell in the others.
        """
        if self.axes is not None:
            raise ValueError(f"{self.source}: rows measured in axes of their own (a part's points) have no "
                             "place in the measurement format, which gives deflections in base axes")
        keep = np.nonzero(self.measured.any(axis=0))[0]
        digits = np.array([6, 6, 6, 7, 7, 7])
        with open(path, "w", newline="") as fh:
            w = csv.writer(fh)
            w.writerow([*REQUIRED_COLS, *(DEFLECTION_COLS[k] for k in keep)])
            for i in range(len(self)):
                w.writerow([
                    _fmt(self.time_s[i], 4), self.config[i],
                    *(_fmt(v, 6) for v in self.q_deg[i]),
                    *(_fmt(v, 4) for v in self.wrench[i]),
                    BODIES[self.body[i]],
                    *(_fmt(self.deflection[i, k], digits[k]) for k in keep),
                ])


def _fmt(v: float, digits: int) -> str:
    """A number for the file; NaN (not measured) is an empty cell."""
    if math.isnan(v):
        return ""
    return f"{v:.{digits}f}".rstrip("0").rstrip(".") if math.isfinite(v) else repr(v)


def read_measurements(path: str | Path, robot: Robot | None = None) -> Dataset:
    """Read and validate a campaign from CSV (or Parquet, with pyarrow installed).

    Every row is checked: missing columns, non-numeric values, NaN or inf, unknown bodies and,
    given a robot, joint angles outside its limits. The problems are collected (the first
    `Problems.LIMIT` kept, the rest counted) and raised together as one DataError naming each line;
    nothing is dropped silently. Rows are checked as they are read, into compact arrays, so memory
    grows with the file, not with its problems. A CSV may start with a UTF-8 byte order mark (Excel).
    """
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: measurement file not found")
    if path.suffix.lower() in (".parquet", ".pq"):
        header, rows = _parquet_rows(path)
        return _validate(path, header, rows, robot)
    try:
        with open(path, newline="", encoding="utf-8-sig") as fh:
            reader = csv.reader(fh)
            header = _csv_header(path, reader)
            return _validate(path, header, _csv_rows(path, reader), robot)
    except OSError as e:
        raise DataError(f"{path}: cannot read: {e.strerror or e}") from e


def _csv_header(path: Path, reader) -> list[str]:
    try:
        header = next(reader)
    except StopIteration:
        raise DataError(f"{path}: the file is empty; expected a header row") from None
    except (csv.Error, UnicodeDecodeError) as e:
        raise DataError(f"{path}: line 1: cannot parse the header: {e}") from e
    return [h.strip() for h in header]


def _csv_rows(path: Path, reader) -> Iterator[tuple[int, list[str]]]:
    """(file line, fields) of every non-blank row."""
    try:
        for row in reader:
            if not row or all(not c.strip() for c in row):
                continue  # blank line: holds no data
            yield reader.line_num, row
    except (csv.Error, UnicodeDecodeError) as e:
        raise DataError(f"{path}: line {reader.line_num}: cannot parse: {e}") from e


def _parquet_rows(path: Path) -> tuple[list[str], Iterator[tuple[int, list[str]]]]:
    table = read_parquet(path)
    header = list(table.column_names)
    cols = [table.column(c).to_pylist() for c in header]
    rows = (["" if v is None else str(v) for v in r] for r in zip(*cols))
    return header, enumerate(rows, start=2)


def _check_header(path: Path, header: list[str]) -> None:
    missing = [c for c in REQUIRED_COLS if c not in header]
    if missing:
        raise DataError(f"{path}: line 1: missing column(s) {', '.join(missing)}; "
                        f"the format needs {', '.join(REQUIRED_COLS)} and at least one of "
                        f"{', '.join(DEFLECTION_COLS)}")
    if not any(c in header for c in DEFLECTION_COLS):
        raise DataError(f"{path}: line 1: no deflection column; give at least one of "
                        f"{', '.join(DEFLECTION_COLS)} (a laser tracker: dx_mm, dy_mm, dz_mm)")
    dup = sorted({c for c in header if header.count(c) > 1})
    if dup:
        raise DataError(f"{path}: line 1: column(s) {', '.join(dup)} appear more than once")


def _validate(path: Path, header: list[str], rows: Iterable[tuple[int, list[str]]],
              robot: Robot | None) -> Dataset:
    _check_header(path, header)
    idx = {c: header.index(c) for c in COLUMNS if c in header}
    problems = Problems()
    num, config, body, lines = array("d"), [], array("b"), array("q")
    body_index = {b: i for i, b in enumerate(BODIES)}
    nan_row = [math.nan] * len(NUMERIC_COLS)
    for line, row in rows:
        lines.append(line)
        if len(row) != len(header):
            problems.add(f"{path}: line {line}: {len(row)} fields, the header has {len(header)}")
            num.extend(nan_row)
            config.append("")
            body.append(-1)
            continue
        num.extend(_numbers(path, line, row, idx, problems))
        if not any(row[idx[c]].strip() for c in DEFLECTION_COLS if c in idx):
            problems.add(f"{path}: line {line}: no deflection component is given; a row must "
                         "measure at least one")
        cfg = row[idx["config"]].strip()
        config.append(cfg)
        if not cfg:
            problems.add(f"{path}: line {line}: config is empty")
        b = row[idx["body"]].strip()
        body.append(body_index.get(b, -1))
        if b not in body_index:
            problems.add(None if problems.full else
                         f"{path}: line {line}: body = {quote(b)} is not one of {', '.join(BODIES)}")
    n = len(lines)
    num_a = np.frombuffer(num, dtype=float).reshape(n, len(NUMERIC_COLS)) if n else np.zeros((0, 19))
    q = num_a[:, 1:7]
    if robot is not None:
        ok = robot.within_limits(np.nan_to_num(q))
        for r, j in zip(*np.nonzero(~ok)):
            lo, hi = robot.limits_deg[j]
            problems.add(f"{path}: line {lines[r]}: q{j + 1}_deg = {q[r, j]:g} is outside the joint "
                         f"limits [{lo:g}, {hi:g}] of {robot.source}")
    if problems:
        raise DataError(f"{path}: {problems.count} problem(s) in {n} rows; nothing was loaded", problems)
    if n == 0:
        raise DataError(f"{path}: no data rows after the header")
    extra = [c for c in header if c not in COLUMNS]
    return Dataset(num_a[:, 0].copy(), np.array(config, dtype=str), q.copy(), num_a[:, 7:13].copy(),
                   np.asarray(body, dtype=int), num_a[:, 13:19].copy(), np.asarray(lines, dtype=int),
                   str(path), extra)


def _numbers(path: Path, line: int, row: list[str], idx: dict[str, int], problems: Problems) -> list[float]:
    """The numeric columns of one row (NaN where a deflection is not measured or a value is bad)."""
    out = []
    for c in NUMERIC_COLS:
        text = row[idx[c]].strip() if c in idx else ""
        v = math.nan
        if text or c not in DEFLECTION_COLS:     # an empty deflection cell: not measured
            try:
                v = float(text)
            except ValueError:
                problems.add(None if problems.full else f"{path}: line {line}: {c} = {quote(text)} is not a number")
            else:
                if not math.isfinite(v):
                    problems.add(None if problems.full else f"{path}: line {line}: {c} = {quote(text)} is not finite")
        out.append(v)
    return out
