"""Time records of the dynamics (a process plan, a force and path for `stiffcomp modes`): CSV with a header
row of named columns, numbers below, '#' lines ignored. The one reader: every problem names the file, the
line and the column.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..errors import DataError, Problems, quote
from ..files.csv_table import read_table


def read_columns(path: str | Path, required: tuple[str, ...], optional: tuple[str, ...] = (),
                 what: str = "record") -> dict[str, np.ndarray]:
    """The named columns of a CSV as float arrays (``required`` all, ``optional`` where present), the rows
    in the file's order; the first column must be ``t_s`` and strictly increase."""
    problems = Problems()
    table = read_table(path, problems, ", ".join(required))
    cols = table.cols
    missing = [c for c in required if c not in cols]
    if missing:
        raise DataError(f"{path}: line {table.header_line}: missing column(s) {', '.join(missing)}; the {what} "
                        f"needs {', '.join(required)}" + (f" (optional: {', '.join(optional)})" if optional else ""))
    names = [c for c in (*required, *optional) if c in cols]
    idx = [cols.index(c) for c in names]
    rows: list[list[float]] = []
    for line, row in table.rows:
        try:
            v = [float(row[i]) for i in idx]
        except ValueError:
            bad = next(c for c, i in zip(names, idx) if not _number(row[i]))
            problems.add(f"{path}: line {line}: {bad} = {quote(row[cols.index(bad)].strip())} is not a number")
            continue
        if not all(math.isfinite(x) for x in v):
            problems.add(f"{path}: line {line}: {names[next(j for j, x in enumerate(v) if not math.isfinite(x))]} "
                         "is not finite")
            continue
        if rows and v[0] <= rows[-1][0]:
            problems.add(f"{path}: line {line}: t_s = {v[0]:g} does not increase (the line before: {rows[-1][0]:g})")
            continue
        rows.append(v)
    if problems:
        raise DataError(f"{path}: {problems.count} problem(s); nothing was loaded", problems)
    if len(rows) < 2:
        raise DataError(f"{path}: {len(rows)} row(s); a {what} needs at least 2")
    data = np.array(rows)
    return {c: data[:, j] for j, c in enumerate(names)}


def check_whole(path: str | Path) -> None:
    """DataError naming ``path``'s last line when the file does not end with a line break: a recorder ends
    every row with one, so a last row without it was cut off (a copy or a recording that stopped), and its
    last number may be cut short while still reading as a number. Nothing when the file is missing (the
    reader says so)."""
    try:
        data = Path(path).read_bytes()
    except OSError:
        return
    if data.strip() and not data.endswith((b"\n", b"\r")):
        raise DataError(f"{path}: line {len(data.splitlines())}: ends without a line break: the file was cut off in "
                        "this line (a copy or a recording that did not finish); record or copy it again, or delete "
                        "the line")


def _number(text: str) -> bool:
    try:
        float(text)
    except ValueError:
        return False
    return True
