"""Reading the generated TwinCAT sources back with blark (TwinCAT's structured-text parser), for the tests.

Everything here comes from the parsed sources, not from the generator's tables: struct fields and their
types, global constants and their values, enum values; byte offsets are summed from the parsed types
(the structs are packed as their ``pack_mode`` says; without it the test checks natural alignment holds).
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from pathlib import Path

from blark.summary import CodeSummary

from st_runtime.source import parse_file

SIZES = {"BOOL": 1, "BYTE": 1, "WORD": 2, "UINT": 2, "INT": 2, "UDINT": 4, "DINT": 4, "REAL": 4, "DWORD": 4}
_ARRAY = re.compile(r"^ARRAY \[(\d+)\.\.(\d+)\] OF (\w+)$")


@dataclass(frozen=True)
class Field:
    name: str
    type: str
    offset: int
    size: int


@functools.cache
def summary(folder: Path, pattern: str = "*") -> CodeSummary:
    """The parsed files of ``folder`` that match ``pattern`` (parsed once per test session: blark takes
    seconds for the blocks)."""
    return CodeSummary.from_parse_results([r for p in sorted(folder.glob(pattern)) for r in parse_file(p)])


def size_of(type_text: str) -> int:
    m = _ARRAY.match(type_text)
    if m:
        return (int(m.group(2)) - int(m.group(1)) + 1) * SIZES[m.group(3)]
    return SIZES[type_text]


def struct_fields(code: CodeSummary, name: str) -> list[Field]:
    out, offset = [], 0
    for field, decl in code.data_types[name].declarations.items():
        size = size_of(str(decl.type))
        out.append(Field(str(field), str(decl.type), offset, size))
        offset += size
    return out


def constant(code: CodeSummary, gvl: str, name: str) -> int:
    """A global constant's integer value (``16#..`` or decimal), as the parsed source writes it."""
    text = str(code.globals[gvl].declarations[name].value)
    return int(text[3:], 16) if text.startswith("16#") else int(text)


def constants(code: CodeSummary, gvl: str, prefix: str) -> dict[str, int]:
    return {str(n)[len(prefix):]: constant(code, gvl, str(n)) for n in code.globals[gvl].declarations
            if str(n).startswith(prefix)}


def enum_values(code: CodeSummary, name: str) -> dict[str, int]:
    return {str(v.name): int(str(v.value)) for v in code.data_types[name].item.init.spec.values}


def packed(path: Path) -> bool:
    return "{attribute 'pack_mode' := '1'}" in path.read_text()
