"""The values of the runtime: IEC 61131-3's elementary types as a PLC holds them (integers wrapping at their
width, REAL as float32), the implicit conversions of IEC 61131-3 ed. 3, and structs laid out in bytes as
TwinCAT lays them (natural alignment, or none with ``pack_mode`` 1), which is where ADR, a request's length and
a peer's registers meet."""

from __future__ import annotations

import math
import re
import struct
from dataclasses import dataclass
from typing import Any

INTS = {"SINT": (8, True), "INT": (16, True), "DINT": (32, True), "LINT": (64, True),
        "USINT": (8, False), "UINT": (16, False), "UDINT": (32, False), "ULINT": (64, False)}
BITS = {"BYTE": 8, "WORD": 16, "DWORD": 32, "LWORD": 64}
REALS = {"REAL": 32, "LREAL": 64}
SIZE = {"BOOL": 1, "TIME": 4, **{t: w // 8 for t, (w, _) in INTS.items()}, **{t: w // 8 for t, w in BITS.items()},
        **{t: w // 8 for t, w in REALS.items()}}
CODE = {"BOOL": "?", "SINT": "b", "INT": "h", "DINT": "i", "LINT": "q", "USINT": "B", "UINT": "H", "UDINT": "I",
        "ULINT": "Q", "BYTE": "B", "WORD": "H", "DWORD": "I", "LWORD": "Q", "REAL": "f", "LREAL": "d", "TIME": "I"}
ANY_INT, ANY_REAL, POINTER = "ANY_INT", "ANY_REAL", "POINTER"
_F32 = struct.Struct("<f")


class StError(Exception):
    """The source is outside the subset, or breaks a typing rule (names the POU and line)."""


@dataclass(frozen=True)
class Arr:
    lower: int
    upper: int
    base: Any


@dataclass(frozen=True)
class Str:
    length: int


def parse_type(text: str):
    """A type as blark's summary spells it: ``ARRAY [1..6] OF REAL``, ``STRING(23)``, a name."""
    m = re.fullmatch(r"ARRAY\s*\[(-?\d+)\.\.(-?\d+)\]\s*OF\s+(.+)", text.strip())
    if m:
        return Arr(int(m.group(1)), int(m.group(2)), parse_type(m.group(3)))
    m = re.fullmatch(r"STRING\((\d+)\)", text.strip())
    if m:
        return Str(int(m.group(1)))
    return text.strip()


def f32(x: float) -> float:
    """``x`` as a REAL holds it: rounded to the nearest float32 (IEEE 754 binary32, ties to even), a value past
    the largest REAL an infinity of its sign (IEEE 754's overflow under round to nearest), NaN and the
    infinities as they are."""
    try:
        return _F32.unpack(_F32.pack(x))[0]
    except OverflowError:            # struct refuses what rounds past FLT_MAX: IEEE 754 gives the infinity
        return math.copysign(math.inf, x)


def wrap(t: str):
    """The store of an integer or bit string type: the value modulo its width (signed types signed)."""
    if t in BITS:
        mask = (1 << BITS[t]) - 1
        return lambda v: v & mask
    width, signed = INTS.get(t, (32, False))      # TIME: a UDINT of ms
    mask, half = (1 << width) - 1, 1 << (width - 1)
    if signed:
        return lambda v: ((v + half) & mask) - half
    return lambda v: v & mask


# -- REAL/LREAL to an integer, and the selections: the PLC's results, never a Python exception -----------------
INDEFINITE = -(1 << 63)              # x86's "integer indefinite" of a 64-bit conversion: 0x8000_0000_0000_0000


def real_to_int(x: float) -> int:
    """``REAL_TO_<int>``/``LREAL_TO_<int>`` (and ``_TO_<bit string>``) before the store wraps it to the type:
    ``x`` rounded to the nearest integer, a tie (2.5) to the even one, as the x86 conversion does (CVTSS2SI and
    CVTSD2SI round by MXCSR's rounding control, round to nearest (even) after reset: Intel 64 and IA-32 SDM
    vol. 1, "Rounding" and "MXCSR Control and Status Register"; vol. 2, CVTSD2SI), the processor TwinCAT runs
    on (Beckhoff, TwinCAT 3 PLC, "REAL/LREAL_TO_<type>": "rounds ... to the nearest integer value", 1.5 -> 2,
    -1.5 -> -2, 1.4 -> 1; its ties are not otherwise said), and what MATIEC computes (lib/C/iec_std_lib.h,
    ``__preal_to_sint``: ``x + 0.5`` truncated, an exact integer halved and doubled; it differs only past 2**52,
    where ``x + 0.5`` itself rounds).

    NaN, the infinities and anything past the 64-bit range give the conversion's "integer indefinite",
    0x8000_0000_0000_0000 (SDM vol. 2, CVTSD2SI, the invalid exception masked), and the store keeps the type's
    low bits of it: 0 for every type up to 32 bits (MATIEC's C gives 0 for NaN too), -2**63 for LINT, 2**63 for
    ULINT and LWORD. A value outside the type's range but inside 64 bits wraps to it (REAL_TO_UINT(-1.0) =
    65535; MATIEC gives 0 for a negative to an unsigned type). Beckhoff calls both results undefined, and with
    the task's floating point exceptions enabled the PLC stops instead (Tc2_Utilities, IsFinite); the runtime
    keeps running with the values above, never an exception."""
    if not math.isfinite(x):
        return INDEFINITE
    n = round(x)                     # Python's round of a float: exact, ties to even
    return n if -(1 << 63) <= n < (1 << 63) else INDEFINITE


def limit(mn, x, mx):
    """``LIMIT(MN, IN, MX)`` with MATIEC's comparisons (lib/C/iec_std_functions.h, ``LIMIT_##TYPENAME``:
    ``IN > MN ? IN < MX ? IN : MX : MN``): a NaN ``IN`` fails ``IN > MN`` and gives ``MN``; a NaN bound is
    returned where its comparison is reached (Beckhoff, Tc2_Utilities RealIsNaN: every relational operator
    with a NaN operand is FALSE)."""
    return (x if x < mx else mx) if x > mn else mn      # noqa: FURB136 (MATIEC's comparisons, in its order)


def minimum(first, *rest):
    """``MIN`` with MATIEC's loop, spelt as its comparison (it is the definition: Python's ``min`` gives the
    same today, by an order of comparison it does not promise) (``__extrem_``: ``op1 = op1 > tmp ? tmp : op1``): a NaN never replaces the
    value so far, nor is it replaced once it is the first operand."""
    for x in rest:
        first = x if first > x else first                  # noqa: FURB136 (as above)
    return first


def maximum(first, *rest):
    """``MAX`` likewise (``op1 = op1 < tmp ? tmp : op1``)."""
    for x in rest:
        first = x if first < x else first                  # noqa: FURB136 (as above)
    return first


def real_div(a: float, b: float) -> float:
    """A REAL or LREAL quotient as IEEE 754 gives it with its exceptions masked (as MATIEC's C runs): a
    division by zero is an infinity of the operands' signs, 0/0 and NaN/0 a NaN."""
    if b == 0:
        if a == 0 or math.isnan(a):
            return math.nan
        return math.copysign(math.inf, a) * math.copysign(1.0, b)
    return a / b



def widens(src, dst) -> bool:
    """Whether IEC 61131-3 ed. 3 converts ``src`` to ``dst`` implicitly (no loss)."""
    if src == dst:
        return True
    if src == ANY_INT:
        return dst in INTS or dst in BITS or dst in REALS
    if src == ANY_REAL:
        return dst in REALS
    if src in INTS and dst in INTS:
        (ws, ss), (wd, sd) = INTS[src], INTS[dst]
        return wd >= ws if ss == sd else (not ss and wd > ws)
    if src in INTS and dst in REALS:
        return INTS[src][0] <= (16 if dst == "REAL" else 32)
    if src == "REAL" and dst == "LREAL":
        return True
    return src in BITS and dst in BITS and BITS[dst] >= BITS[src]


def common(a, b):
    """The type both operands convert to, or None."""
    if widens(a, b):
        return b if b not in (ANY_INT, ANY_REAL) else a
    if widens(b, a):
        return a
    if {a, b} == {ANY_INT, ANY_REAL}:
        return ANY_REAL
    return None


# -- the data's layout, as TwinCAT lays it --------------------------------------------------------------------
class Layout:
    """Byte layout of a struct: (field, type, offset) per elementary or array field, and the size."""

    def __init__(self, fields: list[tuple[str, Any]], packed: bool, lookup):
        self.fields, offset, widest = [], 0, 1
        for name, t in fields:
            size, align = _size_align(t, lookup)
            align = 1 if packed else align
            offset += -offset % align
            self.fields.append((name, t, offset))
            offset += size
            widest = max(widest, align)
        self.size = offset + (-offset % widest)


def _size_align(t, lookup) -> tuple[int, int]:
    if isinstance(t, Arr):
        size, align = _size_align(t.base, lookup)
        return size * (t.upper - t.lower + 1), align
    if isinstance(t, Str):
        return t.length + 1, 1
    if t in SIZE:
        return SIZE[t], min(SIZE[t], 8)
    layout = lookup(t)
    return layout.size, max((_size_align(ft, lookup)[1] for _, ft, _ in layout.fields), default=1)


class Record:
    """A struct value: its fields as attributes; `to_bytes`/`from_bytes` by its `Layout`."""

    __slots__ = ("__dict__", "_type")

    def assign(self, other: Record) -> None:
        for k, v in other.__dict__.items():
            cur = self.__dict__[k]
            if isinstance(cur, Record):
                cur.assign(v)
            elif isinstance(cur, list):
                cur[:] = v
            else:
                self.__dict__[k] = v

    def to_bytes(self) -> bytes:
        out = bytearray(self._type.layout.size)
        for name, t, off in self._type.layout.fields:
            _put(out, off, t, getattr(self, name), self._type.machine)
        return bytes(out)

    def from_bytes(self, data: bytes) -> None:
        for name, t, off in self._type.layout.fields:
            setattr(self, name, _get(data, off, t, self._type.machine, getattr(self, name)))


def _put(out: bytearray, off: int, t, value, machine) -> None:
    if isinstance(t, Arr):
        size = _size_align(t.base, machine.layout)[0]
        for k, v in enumerate(value):
            _put(out, off + k * size, t.base, v, machine)
    elif isinstance(t, str) and t in CODE:
        struct.pack_into("<" + CODE[t], out, off, value)
    else:
        data = value.to_bytes()
        out[off:off + len(data)] = data


def _get(data: bytes, off: int, t, machine, current):
    if isinstance(t, Arr):
        size = _size_align(t.base, machine.layout)[0]
        return [_get(data, off + k * size, t.base, machine, c) for k, c in enumerate(current)]
    if isinstance(t, str) and t in CODE:
        return struct.unpack_from("<" + CODE[t], data, off)[0]
    current.from_bytes(data[off:off + machine.layout(t).size])
    return current


@dataclass
class StructType:
    name: str
    fields: dict[str, Any]                  # name -> type
    layout: Layout
    machine: Any

    def new(self) -> Record:
        r = Record()
        r._type = self
        for n, t in self.fields.items():
            setattr(r, n, self.machine.default(t))
        return r


@dataclass
class EnumType:
    name: str
    values: dict[str, int]


@dataclass
class Pointer:
    """ADR(x): the variable itself (a struct or an array), and its type."""

    target: Any
    type: Any

    def read(self, n: int, machine) -> bytes:
        return self.target.to_bytes()[:n]

    def write(self, data: bytes, machine) -> None:
        whole = bytearray(self.target.to_bytes())
        whole[:len(data)] = data
        self.target.from_bytes(bytes(whole))


