"""The data types of the ADS symbols, as a TwinCAT runtime describes them (index groups 0xF00E, 0xF011).

Every type a symbol uses is one entry in TwinCAT's `AdsDatatypeEntry` layout (TcAdsDef.h; ads-client's
``parseAdsResponseDataType`` reads the same): entryLength, version, hashValue, typeHashValue, size,
offs, dataType (ADST_*), flags (uint32 each), then the lengths of name, type and comment, the number of
array dimensions and of sub-items (uint16 each), then the three strings, each NUL-terminated. Our types
are all base types: no array dimensions, no sub-items, an empty type name, and the flag
``ADSDATATYPEFLAG_DATATYPE``, as TwinCAT 3 gives them.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass

DT_ENTRY = struct.Struct("<IIIIIIIIHHHHH")
DT_VERSION = 1
FLAG_DATATYPE = 0x1                 # ADSDATATYPEFLAG_DATATYPE
# IEC 61131-3 base type -> (ADS data type id ADST_*, size in bytes)
BASE_TYPES = {"BOOL": (33, 1), "INT": (2, 2), "UINT": (18, 2), "DINT": (3, 4), "UDINT": (19, 4),
              "REAL": (4, 4), "LREAL": (5, 8), "STRING(80)": (30, 81)}


@dataclass(frozen=True)
class DataType:
    """One base type: its name, ADS data type id and size."""

    name: str
    ads_type: int
    size: int

    def entry(self) -> bytes:
        """The type's AdsDatatypeEntry."""
        name = self.name.encode("latin-1")
        tail = name + b"\0" + b"\0" + b"\0"                 # name, type "", comment ""
        return DT_ENTRY.pack(DT_ENTRY.size + len(tail), DT_VERSION, zlib.crc32(name), 0, self.size, 0,
                             self.ads_type, FLAG_DATATYPE, len(name), 0, 0, 0, 0) + tail


class DataTypeTable:
    """The types of ``type_names`` (each once, in first-use order), by name and as the upload blob.

    Raises ValueError for a type name that is not a base type this server knows.
    """

    def __init__(self, type_names):
        names = list(dict.fromkeys(type_names))
        unknown = [n for n in names if n not in BASE_TYPES]
        if unknown:
            raise ValueError(f"no ADS data type for {unknown!r}; known: {sorted(BASE_TYPES)}")
        self.types = [DataType(n, *BASE_TYPES[n]) for n in names]
        self._by_name = {t.name.lower(): t for t in self.types}
        self.upload = b"".join(t.entry() for t in self.types)

    def find(self, raw: bytes) -> DataType | None:
        """The type named by ``raw`` (NUL-terminated or not, any case), or None."""
        return self._by_name.get(raw.split(b"\0", 1)[0].decode("latin-1").strip().lower())
