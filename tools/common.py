"""Small helpers shared by the subcommands: loading with clear errors, JSON output."""

from __future__ import annotations

import json
import math
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

import numpy as np

from stiffness.data.measurements import Dataset, read_measurements
from stiffness.errors import ConfigError, OutputError
from stiffness.fit.sanity import resolve_duplicates
from stiffness.model.stiffness_model import StiffnessModel


def load(model_path: str, data_path: str | None = None,
         keep_duplicates: bool = False) -> tuple[StiffnessModel, Dataset | None]:
    """The model and the campaign, with a note on ignored columns and a warning on duplicate rows
    (left out unless ``keep_duplicates``, see `stiffness.fit.sanity`)."""
    model = StiffnessModel.from_yaml(model_path)
    data = read_measurements(data_path, model.robot) if data_path else None
    if data is not None and data.ignored_columns:
        print(f"note: {data_path}: column(s) {', '.join(data.ignored_columns)} are not part of the "
              "format and were not used", file=sys.stderr)
    if data is not None:
        data, warnings = resolve_duplicates(data, keep_duplicates)
        for w in warnings:
            print(f"warning: {w}", file=sys.stderr)
    return model, data


def add_duplicates_option(p) -> None:
    """``--keep-duplicates``: keep rows that repeat an earlier row (shared by fit, diagnose, compare, kcart)."""
    p.add_argument("--keep-duplicates", action="store_true",
                   help="keep rows that repeat an earlier row, or a body measured twice in one reading "
                        "(default: leave them out, with a warning; docs/measurement_format.md)")


class Progress:
    """The progress of a long command (fit, diagnose) on stderr, so stdout stays the result.

    On a terminal: one line rewritten in place with the stage and the seconds so far. Otherwise (a
    log, CI): the first stage, then at most one line every EVERY_S seconds. Both end with
    ``COMMAND: done in X s``.
    """

    EVERY_S = 5.0

    def __init__(self, command: str, stream=None):
        self.command = command
        self.stream = stream or sys.stderr
        self.tty = self.stream.isatty()
        self.t0 = time.monotonic()
        self.last: float | None = None

    def __call__(self, stage: str) -> None:
        now = time.monotonic()
        line = f"{self.command}: {stage} ({now - self.t0:.0f} s)"
        if self.tty:
            print(f"\r\033[K{line}", end="", file=self.stream, flush=True)
        elif self.last is None or now - self.last >= self.EVERY_S:
            print(line, file=self.stream, flush=True)
            self.last = now

    def done(self) -> None:
        print(("\r\033[K" if self.tty else "") + f"{self.command}: done in {time.monotonic() - self.t0:.1f} s",
              file=self.stream, flush=True)


T = TypeVar("T")


def write_output(path: str | Path, write: Callable[[Path], T]) -> T:
    """Run ``write(path)`` after creating the parent folder; OS errors become an OutputError naming the path."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        return write(path)
    except OSError as e:
        raise OutputError(f"{path}: cannot write: {e.strerror or e}") from e


def check_output_file(option: str, path: str | Path) -> Path:
    """The output file ``path`` given as ``option``, checked before any work starts: its folder must exist
    (nothing creates it) and it must not be a folder; OutputError naming the option otherwise."""
    path = Path(path)
    if path.is_dir():
        raise OutputError(f"{option} {path}: is a folder; name a file in it")
    return _in_a_folder(option, path)


def check_image_file(option: str, path: str | Path) -> Path:
    """`check_output_file` for an image: its suffix must also be a format matplotlib writes (the suffix says
    which); OutputError naming the option otherwise."""
    from matplotlib.backend_bases import FigureCanvasBase

    kinds = [f".{s}" for s in FigureCanvasBase.get_supported_filetypes()]
    if Path(path).suffix.lower() not in kinds:
        raise OutputError(f"{option} {path}: the suffix says the image's format; it must be one of {', '.join(kinds)}")
    return check_output_file(option, path)


def check_output_folder(option: str, path: str | Path) -> Path:
    """The output folder ``path`` given as ``option``: it may be new, but its parent must exist and it must not
    be a file; OutputError naming the option otherwise (checked before any work starts)."""
    path = Path(path)
    if path.exists() and not path.is_dir():
        raise OutputError(f"{option} {path}: is a file; name a folder")
    return _in_a_folder(option, path)


def _in_a_folder(option: str, path: Path) -> Path:
    """``path`` if its folder exists (nothing creates it); OutputError naming the option otherwise."""
    if not path.parent.is_dir():
        raise OutputError(f"{option} {path}: the folder {path.parent} does not exist (create it first)")
    return path


def check_number(option: str, value: float, unit: str, *, above: float | None = None,
                 at_least: float | None = None, at_most: float | None = None) -> float:
    """``value`` of ``option`` if it is finite and within the bounds given; ConfigError naming the option
    otherwise (called right after parsing, before any work starts). ``unit`` says what the number is in."""
    bounds = [f"above {above:g}" if above is not None else "", f"at least {at_least:g}" if at_least is not None else "",
              f"at most {at_most:g}" if at_most is not None else ""]
    ok = (math.isfinite(value) and (above is None or value > above) and (at_least is None or value >= at_least)
          and (at_most is None or value <= at_most))
    if not ok:
        raise ConfigError(f"{option} {value:g}: must be a finite number {' and '.join(b for b in bounds if b)} "
                          f"({unit})")
    return value


def check_count(option: str, text: str, *, at_least: int = 1) -> int:
    """``text`` given as ``option`` read as a whole number of at least ``at_least``; ConfigError naming the
    option otherwise (called right after parsing, before any work starts)."""
    try:
        n = int(text)
    except ValueError:
        n = None
    if n is None or n < at_least:
        raise ConfigError(f"{option} {text}: must be a whole number, at least {at_least}")
    return n


def to_jsonable(x: Any) -> Any:
    if isinstance(x, dict):
        return {k: to_jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [to_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return to_jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        return float(x) if np.isfinite(x) else None
    if isinstance(x, np.integer):
        return int(x)
    return x


def print_json(obj: Any) -> None:
    print(json.dumps(to_jsonable(obj), indent=2))
