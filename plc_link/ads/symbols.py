"""The ADS symbol table, as a TwinCAT project shows it, built from the register map.

``GVL_Comp.<register name>`` for every register (index group 0x4020 at the register's %MB offset) and
``TwinCAT_SystemInfoVarList._TaskInfo[1].*`` (index group 0x4040). Writable are exactly the from_plc
registers. Names are matched without regard to case, as TwinCAT does.

The upload encoding (index groups 0xF00B/0xF00C/0xF00F, and 0xF009 per symbol) is AdsLib's
`AdsSymbolEntry`: entryLength, iGroup, iOffs, size, dataType, flags (uint32 each), then the lengths of
name, type and comment (uint16 each), then the three strings, each NUL-terminated.

The symbol version (index group 0xF008) is not the table's but the running device's: `session.Device`
counts it up each time it installs a table whose upload differs from the one it serves.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from plc_link.register_map import RegisterMap

from .area import MB_GROUP, TASKINFO_FIELDS, TASKINFO_GROUP, Layout
from .datatypes import BASE_TYPES, DataTypeTable

GVL = "GVL_Comp"
TASKINFO_PREFIX = "TwinCAT_SystemInfoVarList._TaskInfo[1]"
# register type -> IEC 61131-3 type (its ADS id and size: datatypes.BASE_TYPES)
IEC_TYPES = {"uint16": "UINT", "int16": "INT", "uint32": "UDINT", "int32": "DINT", "float32": "REAL"}
FLAG_READONLY = 1 << 5          # ADSSYMBOLFLAG_READONLY
ENTRY = struct.Struct("<IIIIIIHHH")
UPLOAD_INFO = struct.Struct("<II")
UPLOAD_INFO2 = struct.Struct("<IIIIII")


@dataclass(frozen=True)
class Symbol:
    """One ADS symbol: where its bytes are and whether a client may write them."""

    name: str
    type_name: str
    group: int
    offset: int
    size: int
    writable: bool
    comment: str = ""

    @property
    def ads_type(self) -> int:
        return BASE_TYPES[self.type_name][0]

    def entry(self) -> bytes:
        """The symbol's AdsSymbolEntry (symbol info and upload)."""
        name, typ, comment = (s.encode("latin-1", "replace") for s in (self.name, self.type_name, self.comment))
        tail = name + b"\0" + typ + b"\0" + comment + b"\0"
        flags = 0 if self.writable else FLAG_READONLY
        return ENTRY.pack(ENTRY.size + len(tail), self.group, self.offset, self.size, self.ads_type, flags,
                          len(name), len(typ), len(comment)) + tail

    def as_dict(self) -> dict:
        return {"name": self.name, "type": self.type_name, "index_group": self.group,
                "index_offset": self.offset, "size": self.size, "writable": self.writable}


def symbols_from_map(rmap: RegisterMap) -> list[Symbol]:
    """Every symbol the server offers, register symbols first, in register map order."""
    layout = Layout(rmap)
    out = []
    for r in rmap.registers:
        typ = IEC_TYPES[r.type]
        size = BASE_TYPES[typ][1]
        unit = f" [{r.unit}]" if r.unit else ""
        scale = f" (raw = value * {r.scale:g})" if r.scale != 1.0 else ""
        out.append(Symbol(f"{GVL}.{r.name}", typ, MB_GROUP, layout.mb_offset(r), size,
                          r.direction == "from_plc", f"{r.description}{unit}{scale}".strip()))
    for name, typ, offset, source, _ in TASKINFO_FIELDS:
        out.append(Symbol(f"{TASKINFO_PREFIX}.{name}", typ, TASKINFO_GROUP, offset, BASE_TYPES[typ][1], False,
                          f"from {source}"))
    return out


class SymbolTable:
    """Symbols by name (case-insensitive), their data types and the upload blobs, built once."""

    def __init__(self, rmap: RegisterMap):
        self.symbols = symbols_from_map(rmap)
        self._by_name = {s.name.lower(): s for s in self.symbols}
        self.types = DataTypeTable(s.type_name for s in self.symbols)
        self.upload = b"".join(s.entry() for s in self.symbols)
        self.upload_info = UPLOAD_INFO.pack(len(self.symbols), len(self.upload))
        self.upload_info2 = UPLOAD_INFO2.pack(len(self.symbols), len(self.upload), len(self.types.types),
                                              len(self.types.upload), 0, 0)

    def find(self, raw: bytes) -> Symbol | None:
        """The symbol named by ``raw`` (a name as a client sends it, NUL-terminated or not), or None."""
        name = raw.split(b"\0", 1)[0].decode("latin-1").strip().lower()
        return self._by_name.get(name)
