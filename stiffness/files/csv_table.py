"""A CSV a person or an instrument writes: '#' lines first (kept: they may hold a header), a row of column
names, rows of fields. The one reader of its layout and of its '# key: value' header (`Table.header`, checked
against the format's schema): rows with the wrong number of fields become problems that name the file and the
line; what the fields and the keys mean is the caller's (a part file, a probe log, a process plan, a force and
path record).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ValidationError

from ..errors import DataError, Problems, quote
from .yaml_schema import format_validation_error
from .yaml_syntax import NoAliasLoader

H = TypeVar("H", bound=BaseModel)


class _HeaderLoader(NoAliasLoader):
    """The '# key: value' lines' loader: a key given twice is refused at its second line (PyYAML keeps the last
    in silence, and a header's second radius would pass for the first)."""

    def construct_mapping(self, node, deep=False):
        seen: dict[Any, int] = {}
        for key_node, _ in node.value:
            key = _key(self.construct_object(key_node, deep=True))
            line = key_node.start_mark.line + 1
            if key in seen:
                raise _GivenTwice(f"line {line}: {key} is given twice (line {seen[key]} and line {line}); keep "
                                  "the one that is right")
            seen[key] = line
        return super().construct_mapping(node, deep)


class _GivenTwice(Exception):
    pass


@dataclass
class Table:
    """The '#' lines (without the '#'), the header's line (from 1), the column names and the data rows
    (line, fields), each with as many fields as the header."""

    head: list[str]
    header_line: int
    cols: list[str]
    rows: list[tuple[int, list[str]]]

    def header(self, path, schema: type[H], keys: str,
               refuse: Callable[[dict[str, Any]], None] | None = None) -> H:
        """The '#' lines, 'key: value' lines with spaces in keys read as '_', validated as ``schema``. DataError
        at the file's line when they are not valid YAML, not a mapping (``keys``: the keys expected, for the
        message) or give a key twice; then whatever ``refuse`` raises of the mapping (what the format refuses
        in words of its own); then one line for each key the schema refuses."""
        data = self._mapping(path, keys)
        if refuse is not None:
            refuse(data)
        try:
            return schema.model_validate(data)
        except ValidationError as e:
            raise DataError(format_validation_error(str(path), e)) from None

    def _mapping(self, path, keys: str) -> dict[str, Any]:
        try:
            data = yaml.load("\n".join(self.head), Loader=_HeaderLoader) or {}
        except _GivenTwice as e:
            raise DataError(f"{path}: {e}") from None
        except yaml.YAMLError as e:
            mark = getattr(e, "problem_mark", None)
            where = f" line {mark.line + 1}" if mark is not None else ""
            raise DataError(f"{path}:{where}: the '# key: value' lines are not valid YAML: "
                            f"{getattr(e, 'problem', e)}") from None
        if not isinstance(data, dict):
            raise DataError(f"{path}: the '#' lines must be 'key: value' lines ({keys})")
        return {_key(k): v for k, v in data.items()}

    def numbers(self, path, names: list[str], problems: Problems, what: str, noun: str):
        """(line, fields, values) of each row whose columns ``names`` hold finite numbers; a row that does not
        is added to ``problems`` naming the line (``what`` must be numbers; a ``noun`` is not finite) and left
        out."""
        idx = [self.cols.index(c) for c in names]
        for line, row in self.rows:
            try:
                v = [float(row[i]) for i in idx]
            except ValueError:
                problems.add(f"{path}: line {line}: {what} must be numbers, got "
                             f"{', '.join(quote(row[i].strip()) for i in idx)}")
                continue
            if not all(math.isfinite(x) for x in v):
                problems.add(f"{path}: line {line}: a {noun} is not finite")
                continue
            yield line, row, v


def peek(path: str | Path) -> tuple[set[str], set[str]]:
    """The keys of ``path``'s '# key: value' lines (spaces read as '_') and the names of its header row, read
    without a judgement, for telling one kind of file from another; both empty when it cannot be read."""
    try:
        with open(path, encoding="utf-8-sig") as f:
            head, row = _layout(f)
    except (OSError, UnicodeDecodeError):
        return set(), set()
    keys = {_key(line.split(":", 1)[0].strip()) for line in head if line.strip()}
    return keys, set() if row is None else {c.strip() for c in row.split(",")}


def read_table(path: str | Path, problems: Problems, expected: str) -> Table:
    """``path``'s table; a row with the wrong number of fields is added to ``problems`` and left out.
    DataError when the file is missing, unreadable or has no header row (``expected`` says which columns)."""
    path = Path(path)
    if not path.exists():
        raise DataError(f"{path}: file not found")
    try:
        text = path.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as e:
        raise DataError(f"{path}: cannot read: {e}") from e
    lines = text.splitlines()
    head, row = _layout(lines)
    k = len(head)
    if row is None:
        raise DataError(f"{path}: no header row after the '#' lines; expected {expected}")
    if ";" in lines[k] and "," not in lines[k]:
        raise DataError(f"{path}: line {k + 1}: the fields are separated by ';', where the format separates them by "
                        "',' and writes decimals with '.' (a spreadsheet's export in another locale?): save it as "
                        f"comma-separated; expected {expected}")
    reader = csv.reader(io.StringIO("\n".join(lines[k:])))
    cols = [c.strip() for c in next(reader)]
    rows, wrong = [], []
    for n, row in enumerate(reader):
        line = k + 2 + n
        if not row or all(not c.strip() for c in row):
            continue
        if len(row) != len(cols):
            problems.add(f"{path}: line {line}: {len(row)} fields, the header has {len(cols)}")
            wrong.append((line, len(row) > len(cols)))
            continue
        rows.append((line, row))
    if wrong and not rows and all(more for _, more in wrong):
        raise DataError(f"{path}: line {wrong[0][0]}: every row has more fields than the header's {len(cols)}: "
                        "decimal commas? The format writes decimals with '.' and separates the fields by ','")
    return Table(head, k + 1, cols, rows)


def _layout(lines: Iterable[str]) -> tuple[list[str], str | None]:
    """The lines before the header row, each '#' line without its '#' and a blank line as '', and the header row
    (None when there is none)."""
    head = []
    for line in lines:
        if not line.startswith("#") and line.strip():
            return head, line
        head.append(line[1:] if line.startswith("#") else "")
    return head, None


def _key(name: Any) -> str:
    """A header key as the formats name it: spaces read as '_'."""
    return str(name).replace(" ", "_")


def given_twice(path, labels: list[str], lines: list[int], noun: str, problems: Problems) -> None:
    """Each ``noun`` whose label repeats an earlier one's, added to ``problems`` at its line: a file pasted in
    twice would count every point twice, and a model learned from it would be twice as sure as the part allows."""
    first: dict[str, int] = {}
    for label, line in zip(labels, lines):
        if label in first:
            problems.add(f"{path}: line {line}: {noun} {label} is given twice (line {first[label]} and line {line})")
        else:
            first[label] = line
