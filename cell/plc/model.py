"""The PLC library's objects as data: types, variables, structs, enums, variable lists, GVLs and POUs.

Each output format (`twincat`, `plcopen`) renders the same objects; the structured text of the
declarations is written here once (`declaration`), so a TwinCAT file and the PLCopen file cannot say two
different things. A type is an object (`Elementary`, `StringType`, `ArrayType`, `Derived`): its ``st``
is how structured text spells it, and the PLCopen writer renders the same object as XML, so no format
reads a type back from text.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass(frozen=True)
class Elementary:
    """An IEC 61131-3 elementary type (``BOOL``, ``WORD``, ``UINT``, ``REAL``, ``TIME``...)."""

    name: str

    @property
    def st(self) -> str:
        return self.name


@dataclass(frozen=True)
class StringType:
    """``STRING(length)``: at most ``length`` characters."""

    length: int

    @property
    def st(self) -> str:
        return f"STRING({self.length})"


@dataclass(frozen=True)
class ArrayType:
    """``ARRAY[lower..upper] OF base``."""

    lower: int
    upper: int
    base: Type

    @property
    def st(self) -> str:
        return f"ARRAY[{self.lower}..{self.upper}] OF {self.base.st}"


@dataclass(frozen=True)
class Derived:
    """A named type: a struct, an enum or a function block (the library's own or a PLC library's)."""

    name: str

    @property
    def st(self) -> str:
        return self.name


Type = Elementary | StringType | ArrayType | Derived

BOOL, BYTE, WORD, DWORD = Elementary("BOOL"), Elementary("BYTE"), Elementary("WORD"), Elementary("DWORD")
INT, UINT, DINT, UDINT = Elementary("INT"), Elementary("UINT"), Elementary("DINT"), Elementary("UDINT")
REAL, TIME = Elementary("REAL"), Elementary("TIME")
JOINTS_REAL = ArrayType(1, 6, REAL)


@dataclass(frozen=True)
class Var:
    """One declaration: name, type, initial value (structured text, "" for none), comment, and where the
    variable is located (``%I*``: an input the I/O configuration links to a device's process data; "" for
    none)."""

    name: str
    type: Type
    init: str = ""
    comment: str = ""
    at: str = ""

    def line(self) -> str:
        init = f" := {self.init}" if self.init else ""
        comment = f" // {self.comment}" if self.comment else ""
        at = f" AT {self.at}" if self.at else ""
        return f"    {self.name}{at} : {self.type.st}{init};{comment}"


@dataclass(frozen=True)
class Struct:
    name: str
    fields: tuple[Var, ...]
    comment: str = ""
    pack: bool = False          # {attribute 'pack_mode' := '1'}: no padding between fields


@dataclass(frozen=True)
class Enum:
    name: str
    base: Elementary
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


@dataclass(frozen=True)
class Task:
    """The cyclic task the example program runs in (the PLCopen configuration's resource holds it)."""

    name: str
    interval_ms: float
    priority: int
    program: str                # the PROGRAM it calls


@dataclass
class Library:
    """Everything the generator writes, in the order a project needs it (types first)."""

    types: list[Struct | Enum] = field(default_factory=list)
    gvls: list[Gvl] = field(default_factory=list)
    pous: list[Pou] = field(default_factory=list)
    task: Task | None = None


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
        lines += [f") {obj.base.st};", "END_TYPE"]
    elif isinstance(obj, Gvl):
        lines += ["{attribute 'qualified_only'}", *_var_lists(obj.lists)]
    else:
        lines += [f"{obj.kind} {obj.name}", *_var_lists(obj.lists)]
    return "\n".join(lines) + "\n"
