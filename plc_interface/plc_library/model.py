"""The PLC library's objects as data: variables, structs, enums, variable lists, GVLs and POUs.

Each output format (`twincat`, `plcopen`) renders the same objects; the structured text of the
declarations is written here once (`declaration`), so a TwinCAT file and the PLCopen file cannot say two
different things. Types are written as structured text (``UINT``, ``ARRAY[1..6] OF REAL``, ``STRING(23)``,
a struct's or a block's name); `parse_type` reads them back for the PLCopen writer.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

ELEMENTARY = ("BOOL", "BYTE", "WORD", "DWORD", "LWORD", "SINT", "INT", "DINT", "LINT", "USINT", "UINT",
              "UDINT", "ULINT", "REAL", "LREAL", "TIME", "DATE", "DT", "TOD")
_ARRAY = re.compile(r"^ARRAY\[(-?\d+)\.\.(-?\d+)\] OF (.+)$")
_STRING = re.compile(r"^STRING\((\d+)\)$")


@dataclass(frozen=True)
class Var:
    """One declaration: name, type (structured text), initial value (structured text, "" for none), comment."""

    name: str
    type: str
    init: str = ""
    comment: str = ""

    def line(self) -> str:
        init = f" := {self.init}" if self.init else ""
        comment = f" // {self.comment}" if self.comment else ""
        return f"    {self.name} : {self.type}{init};{comment}"


@dataclass(frozen=True)
class Struct:
    name: str
    fields: tuple[Var, ...]
    comment: str = ""
    pack: bool = False          # {attribute 'pack_mode' := '1'}: no padding between fields


@dataclass(frozen=True)
class Enum:
    name: str
    base: str
    values: tuple[tuple[str, int, str], ...]      # name, value, comment
    comment: str = ""


@dataclass(frozen=True)
class VarList:
    kind: str                   # VAR_INPUT, VAR_OUTPUT, VAR, VAR_GLOBAL
    vars: tuple[Var, ...]
    constant: bool = False


@dataclass(frozen=True)
class Gvl:
    name: str
    lists: tuple[VarList, ...]
    comment: str = ""


@dataclass(frozen=True)
class Pou:
    name: str
    kind: str                   # FUNCTION_BLOCK or PROGRAM
    lists: tuple[VarList, ...]
    body: str
    comment: str = ""


@dataclass
class Library:
    """Everything the generator writes, in the order a project needs it (types first)."""

    types: list[Struct | Enum] = field(default_factory=list)
    gvls: list[Gvl] = field(default_factory=list)
    pous: list[Pou] = field(default_factory=list)


def _comment_block(text: str) -> list[str]:
    return [f"// {line}" if line else "//" for line in text.splitlines()] if text else []


def _var_lists(lists: tuple[VarList, ...]) -> list[str]:
    out = []
    for vl in lists:
        out.append(vl.kind + (" CONSTANT" if vl.constant else ""))
        out += [v.line() for v in vl.vars]
        out.append("END_VAR")
    return out


def declaration(obj: Struct | Enum | Gvl | Pou) -> str:
    """The structured text of ``obj``'s declaration (TwinCAT's Declaration section)."""
    lines = _comment_block(obj.comment)
    if isinstance(obj, Struct):
        if obj.pack:
            lines.append("{attribute 'pack_mode' := '1'}")
        lines += [f"TYPE {obj.name} :", "STRUCT", *(v.line() for v in obj.fields), "END_STRUCT", "END_TYPE"]
    elif isinstance(obj, Enum):
        lines += ["{attribute 'qualified_only'}", f"TYPE {obj.name} :", "("]
        for k, (name, value, comment) in enumerate(obj.values):
            sep = "," if k < len(obj.values) - 1 else ""
            lines.append(f"    {name} := {value}{sep}" + (f" // {comment}" if comment else ""))
        lines += [f") {obj.base};", "END_TYPE"]
    elif isinstance(obj, Gvl):
        lines += ["{attribute 'qualified_only'}", *_var_lists(obj.lists)]
    else:
        lines += [f"{obj.kind} {obj.name}", *_var_lists(obj.lists)]
    return "\n".join(lines) + "\n"


@dataclass(frozen=True)
class TypeRef:
    """A parsed type: ``kind`` elementary, string, array or derived."""

    kind: str
    name: str = ""
    length: int = 0
    lower: int = 0
    upper: int = 0
    base: TypeRef | None = None


def parse_type(text: str) -> TypeRef:
    """The `TypeRef` of a type written as structured text."""
    m = _ARRAY.match(text)
    if m:
        return TypeRef("array", lower=int(m.group(1)), upper=int(m.group(2)), base=parse_type(m.group(3)))
    m = _STRING.match(text)
    if m:
        return TypeRef("string", length=int(m.group(1)))
    if text in ELEMENTARY:
        return TypeRef("elementary", text)
    return TypeRef("derived", text)
