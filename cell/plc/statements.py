"""Structured-text statements as data, and the one routine that writes them (`render`).

The blocks' fixed logic is whole named templates (`blocks`); the statements that depend on the register
map (the records' fields, their scaling, the decoded bits) are built as these objects and rendered here,
so no statement is assembled from fragments of text.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Pin:
    """One input of a call: ``name := value``."""

    name: str
    value: str


@dataclass(frozen=True)
class Assign:
    target: str
    value: str


@dataclass(frozen=True)
class If:
    condition: str
    then: tuple[Statement, ...]
    orelse: tuple[Statement, ...] = ()


@dataclass(frozen=True)
class Case:
    """``CASE selector OF label: ...; END_CASE`` (the labels are integer literals)."""

    selector: str
    branches: tuple[tuple[int, tuple[Statement, ...]], ...]


@dataclass(frozen=True)
class Call:
    """A function block instance called with its inputs."""

    instance: str
    pins: tuple[Pin, ...]


Statement = Assign | If | Case | Call
INDENT = "    "


def render(statements: tuple[Statement, ...] | list[Statement], depth: int = 0) -> str:
    """The structured text of ``statements``, one per line, indented ``depth`` levels."""
    return "\n".join(_lines(statements, depth))


def _lines(statements, depth: int) -> list[str]:
    pad = INDENT * depth
    out: list[str] = []
    for s in statements:
        if isinstance(s, Assign):
            out.append(f"{pad}{s.target} := {s.value};")
        elif isinstance(s, Call):
            if len(s.pins) <= 4:
                out.append(f"{pad}{s.instance}(" + ", ".join(f"{p.name} := {p.value}" for p in s.pins) + ");")
            else:
                sep = ",\n" + pad + INDENT
                out.append(f"{pad}{s.instance}(\n{pad}{INDENT}" + sep.join(f"{p.name} := {p.value}" for p in s.pins)
                           + ");")
        elif isinstance(s, If):
            out.append(f"{pad}IF {s.condition} THEN")
            out += _lines(s.then, depth + 1)
            if s.orelse:
                out.append(f"{pad}ELSE")
                out += _lines(s.orelse, depth + 1)
            out.append(f"{pad}END_IF")
        else:
            out.append(f"{pad}CASE {s.selector} OF")
            for label, body in s.branches:
                out.append(f"{pad}{INDENT}{label}:")
                out += _lines(body, depth + 2)
            out.append(f"{pad}END_CASE")
    return out
