"""A small IEC 61131-3 structured-text machine for the PLC library's tests: it runs the generated blocks.

No IEC compiler is packaged here (MATIEC is not in the package lists), so the tests execute blark's parse
tree of the generated sources (blark: TwinCAT's structured-text grammar). Each POU's statements are
translated once into a Python function over the POU's variables, then called every cycle of a simulated
task; time is the runtime's clock (`Runtime.now_ms`), stepped by the test, never the wall clock.

The machine covers the subset the generator writes, with IEC's rules where they catch the mistakes a
compiler would:

* types are checked statically, strictly: AND, OR, XOR and NOT take BOOL or bit strings (BYTE, WORD,
  DWORD, LWORD), never UINT; an assignment takes the target's type, a literal, or an implicit widening of
  IEC 61131-3 ed. 3 (USINT -> UINT, INT -> REAL, ...); an enum only its own values; X_TO_Y takes an X;
* values behave as on the PLC: integers wrap at their width on store, REAL is float32 (every result is
  rounded to it), REAL_TO_<int> rounds half away from zero (Beckhoff: "the value is rounded");
* structs and arrays are copied on assignment (into the target, so ADR of a buffer stays valid); a struct's
  bytes are laid out as TwinCAT lays them (natural alignment, or none with ``pack_mode`` 1), which is what
  ADR, a request's length and the service's registers meet at;
* the PLC library's blocks are Python classes with their manuals' pins: TON, TP and R_TRIG (IEC 61131-3),
  ADSREAD and ADSWRITE (Tc2_System), FB_MBReadRegs, FB_MBReadInputRegs and FB_MBWriteRegs (TF6250,
  Tc2_ModbusSrv); a request runs over a `Network` the test provides, which decides how long it takes and
  serves it against the service's side.

A construct outside the subset is an error naming the POU and line, never a silent no-op.
"""

from __future__ import annotations

import math
import re
import struct
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar

from blark import transform as tf
from blark.summary import CodeSummary
from plc_source import parse_file

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
    return _F32.unpack(_F32.pack(x))[0] if math.isfinite(x) and abs(x) < 3.4e38 else float(x)


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


def round_half_away(x: float) -> int:
    return math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5)


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


# -- the PLC library's blocks -------------------------------------------------------------------------------
class Block:
    """A function block instance: its variables as attributes, `body` runs one call."""

    INPUTS: ClassVar[dict[str, Any]] = {}
    OUTPUTS: ClassVar[dict[str, Any]] = {}
    LOCALS: ClassVar[dict[str, Any]] = {}

    def __init__(self, machine):
        self._m = machine
        for n, t in {**self.INPUTS, **self.OUTPUTS, **self.LOCALS}.items():
            setattr(self, n, machine.default(t))


class TON(Block):
    """IEC 61131-3 on-delay: Q once IN has been TRUE for PT; ET the time so far."""

    INPUTS, OUTPUTS = {"IN": "BOOL", "PT": "TIME"}, {"Q": "BOOL", "ET": "TIME"}

    def body(self) -> None:
        now = self._m.runtime.now_ms
        if not self.IN:
            self._start, self.Q, self.ET = None, False, 0
            return
        if getattr(self, "_start", None) is None:
            self._start = now
        self.ET = min(now - self._start, self.PT)
        self.Q = self.ET >= self.PT


class TP(Block):
    """IEC 61131-3 pulse: a rising edge of IN (while no pulse runs) sets Q for PT."""

    INPUTS, OUTPUTS = {"IN": "BOOL", "PT": "TIME"}, {"Q": "BOOL", "ET": "TIME"}

    def body(self) -> None:
        now = self._m.runtime.now_ms
        start = getattr(self, "_start", None)
        if start is None and self.IN and not getattr(self, "_last", False):
            start = self._start = now
        if start is not None:
            self.ET = min(now - start, self.PT)
            self.Q = self.ET < self.PT
            if not self.Q and not self.IN:
                self._start, self.ET = None, 0
        self._last = self.IN


class R_TRIG(Block):
    INPUTS, OUTPUTS = {"CLK": "BOOL"}, {"Q": "BOOL"}

    def body(self) -> None:
        self.Q = self.CLK and not getattr(self, "_m_clk", False)
        self._m_clk = self.CLK


class Request(Block):
    """A request block: a rising edge of its execute pin starts one over the runtime's `Network`, which says
    how long it takes; the service handles it halfway through, and the block ends it (busy FALSE, error
    and error id) when that time is over, or with a timeout error at its timeout."""

    PINS = ("", "", "", "", "")      # execute, busy, error, error id, timeout: the pins' names
    KIND = ""
    TIMEOUT_ERROR = 1861            # ADSERR_CLIENT_SYNCTIMEOUT (0x745), TF6250 reports the same ADS error

    def body(self) -> None:
        now, net = self._m.runtime.now_ms, self._m.runtime.network
        run = getattr(self, "_run", None)
        execute_pin, busy, error_pin, error_id, timeout_pin = self.PINS
        execute = getattr(self, execute_pin)
        if run is None and execute and not getattr(self, "_last", False):
            took = net.duration(self.KIND, now)
            timeout = getattr(self, timeout_pin)
            self._run = run = {"served_at": now + took // 2, "due": now + min(took, timeout),
                               "late": took > timeout, "served": False, "error": 0}
            setattr(self, busy, True)
            setattr(self, error_pin, False)
            setattr(self, error_id, 0)
            if self.KIND == "write":                # the request carries the source's bytes as they are now
                run["data"] = self.source()
        if run is not None:
            if not run["served"] and now >= run["served_at"]:
                run["served"] = True
                run["error"] = self.serve(net, run)
            if now >= run["due"] and run["served"]:
                error = self.TIMEOUT_ERROR if run["late"] else run["error"]
                setattr(self, busy, False)
                setattr(self, error_pin, error != 0)
                setattr(self, error_id, error)
                self._run = None
        self._last = execute


_ADS_IN = {"NETID": Str(23), "PORT": "UINT", "IDXGRP": "UDINT", "IDXOFFS": "UDINT", "LEN": "UDINT", "TMOUT": "TIME"}
_ADS_OUT = {"BUSY": "BOOL", "ERR": "BOOL", "ERRID": "UDINT"}


class ADSREAD(Request):
    INPUTS, OUTPUTS = {**_ADS_IN, "DESTADDR": POINTER, "READ": "BOOL"}, _ADS_OUT
    PINS, KIND = ("READ", "BUSY", "ERR", "ERRID", "TMOUT"), "read"

    def serve(self, net, run) -> int:
        err, data = net.ads_read(self.IDXGRP, self.IDXOFFS, self.LEN)
        if not err:
            self.DESTADDR.write(data, self._m)
        return err


class ADSWRITE(Request):
    INPUTS, OUTPUTS = {**_ADS_IN, "SRCADDR": POINTER, "WRITE": "BOOL"}, _ADS_OUT
    PINS, KIND = ("WRITE", "BUSY", "ERR", "ERRID", "TMOUT"), "write"

    def source(self) -> bytes:
        return self.SRCADDR.read(self.LEN, self._m)

    def serve(self, net, run) -> int:
        return net.ads_write(self.IDXGRP, self.IDXOFFS, run["data"])


_MB_IN = {"sIPAddr": Str(15), "nTCPPort": "UINT", "nUnitID": "BYTE", "nQuantity": "WORD", "nMBAddr": "WORD",
          "cbLength": "UDINT", "bExecute": "BOOL", "tTimeout": "TIME"}
_MB_OUT = {"bBusy": "BOOL", "bError": "BOOL", "nErrId": "UDINT", "cbRead": "UDINT"}
MODBUS_EXCEPTION = 0x8000           # TF6250: nErrId 16#8000 + the Modbus exception code


class _MbRead(Request):
    INPUTS, OUTPUTS = {**_MB_IN, "pDestAddr": POINTER}, _MB_OUT
    PINS, KIND = ("bExecute", "bBusy", "bError", "nErrId", "tTimeout"), "read"
    TABLE = ""

    def serve(self, net, run) -> int:
        if self.cbLength != 2 * self.nQuantity:
            raise StError(f"{type(self).__name__}: cbLength {self.cbLength} is not 2 x nQuantity {self.nQuantity}")
        words = net.modbus_read(self.TABLE, self.nMBAddr, self.nQuantity)
        if words is None:
            return MODBUS_EXCEPTION + 2
        self.pDestAddr.write(struct.pack(f"<{len(words)}H", *words), self._m)
        self.cbRead = 2 * len(words)
        return 0


class FB_MBReadRegs(_MbRead):
    TABLE = "holding_registers"


class FB_MBReadInputRegs(_MbRead):
    TABLE = "input_registers"


class FB_MBWriteRegs(Request):
    INPUTS, OUTPUTS = {**_MB_IN, "pSrcAddr": POINTER}, {k: v for k, v in _MB_OUT.items() if k != "cbRead"}
    PINS, KIND = ("bExecute", "bBusy", "bError", "nErrId", "tTimeout"), "write"

    def source(self) -> bytes:
        if self.cbLength != 2 * self.nQuantity:
            raise StError(f"FB_MBWriteRegs: cbLength {self.cbLength} is not 2 x nQuantity {self.nQuantity}")
        return self.pSrcAddr.read(self.cbLength, self._m)

    def serve(self, net, run) -> int:
        data = run["data"]
        words = list(struct.unpack(f"<{len(data) // 2}H", data))
        return 0 if net.modbus_write("holding_registers", self.nMBAddr, words) else MODBUS_EXCEPTION + 2


LIBRARY = {c.__name__: c for c in (TON, TP, R_TRIG, ADSREAD, ADSWRITE, FB_MBReadRegs, FB_MBReadInputRegs,
                                   FB_MBWriteRegs)}
# TwinCAT's task info (Tc2_System PlcTaskSystemInfo), the fields the library reads
TASK_INFO = {"CycleTime": "UDINT", "CycleCount": "UDINT", "LastExecTime": "UDINT"}


class Runtime:
    """The simulated PLC runtime: its clock (ms), its task's cycle time, and the network requests go over."""

    def __init__(self, network, cycle_ms: int = 1):
        self.now_ms = 0
        self.cycle_ms = cycle_ms
        self.network = network


# -- the translator -----------------------------------------------------------------------------------------
def _literal_value(text: str, t):
    """A declaration's initial value as blark's summary gives it (``16#0001``, ``TIME#100MS``, ``'x'``)."""
    text = text.strip()
    if text.startswith("'"):
        return text[1:-1]
    if text.upper() in ("TRUE", "FALSE"):
        return text.upper() == "TRUE"
    m = re.fullmatch(r"(?:T|TIME)#(?:(\d+)S)?(?:(\d+)MS)?", text, re.IGNORECASE)
    if m:
        return int(m.group(1) or 0) * 1000 + int(m.group(2) or 0)
    if text.startswith("16#"):
        return int(text[3:].replace("_", ""), 16)
    if t in REALS:
        return f32(float(text)) if t == "REAL" else float(text)
    return int(text)


class Namespace:
    """A global variable list: its values as attributes."""


class Machine:
    """The POUs, types and global lists of a set of parsed sources, ready to run on ``runtime``.

    Parameters
    ----------
    code : blark.summary.CodeSummary of the sources
    packed : names of the structs declared with ``{attribute 'pack_mode' := '1'}``
    runtime : Runtime
    """

    def __init__(self, code, packed: set[str], runtime: Runtime):
        self.runtime = runtime
        self.types: dict[str, Any] = {}
        for name, dt in code.data_types.items():
            if isinstance(dt.item, tf.EnumeratedTypeDeclaration):
                values = {str(v.name): int(str(v.value)) for v in dt.item.init.spec.values}
                self.types[name.lower()] = EnumType(name, values)
        self._structs = {name: ({str(n): parse_type(str(d.type)) for n, d in dt.declarations.items()},
                                name in packed) for name, dt in code.data_types.items()
                         if not isinstance(dt.item, tf.EnumeratedTypeDeclaration)}
        self._structs["PlcTaskSystemInfo"] = (dict(TASK_INFO), False)
        for name, (fields, pack) in self._structs.items():
            self.types[name.lower()] = StructType(name, fields, None, self)
        for t in [t for t in self.types.values() if isinstance(t, StructType)]:
            t.layout = self.layout(t.name)
        self.blocks: dict[str, type] = {n.lower(): c for n, c in LIBRARY.items()}
        self.globals: dict[str, tuple[str, dict[str, Any], set[str]]] = {}     # lower -> (name, types, constants)
        self.namespace: dict[str, Any] = {"f32": f32, "Pointer": Pointer, "StError": StError, "rha": round_half_away,
                                          "idiv": lambda a, b: int(a / b) if isinstance(a, float) else
                                          (abs(a) // abs(b)) * (1 if (a >= 0) == (b >= 0) else -1)}
        for t in (*INTS, *BITS, "TIME"):
            self.namespace[f"W_{t}"] = wrap(t)
        for name, gvl in code.globals.items():
            ns, types, constants = Namespace(), {}, set()
            for n, d in gvl.declarations.items():
                t = parse_type(str(d.type))
                types[str(n)] = t
                value = str(d.value)
                setattr(ns, str(n), self.default(t) if value == "None" else _literal_value(value, t))
                if "CONSTANT" in str(getattr(gvl.item, "attrs", "") or "").upper():
                    constants.add(str(n))
            self.globals[name.lower()] = (name, types, constants)
            self.namespace[f"G_{name}"] = ns
        info = self.types["plctasksysteminfo"].new()
        info.CycleTime = runtime.cycle_ms * 10_000          # TwinCAT: multiples of 100 ns
        system = Namespace()
        system._TaskInfo = [info]
        self.globals["twincat_systeminfovarlist"] = ("TwinCAT_SystemInfoVarList",
                                                     {"_TaskInfo": Arr(1, 1, "PlcTaskSystemInfo")}, {"_TaskInfo"})
        self.namespace["G_TwinCAT_SystemInfoVarList"] = system
        pous = {**code.function_blocks, **code.programs}
        for name, pou in pous.items():        # interfaces first: a body may call any block
            inputs, outputs, local, inits = {}, {}, {}, {}
            for n, d in pou.declarations.items():
                t = parse_type(str(d.type))
                kind = str(d.block).upper()
                (inputs if kind == "VAR_INPUT" else outputs if kind == "VAR_OUTPUT" else local)[str(n)] = t
                if str(d.value) != "None":
                    inits[str(n)] = _literal_value(str(d.value), t)
            cls = type(name, (Block,), {"INPUTS": inputs, "OUTPUTS": outputs, "LOCALS": local, "INITS": inits})
            self.blocks[name.lower()] = cls
        for name, pou in pous.items():
            cls = self.blocks[name.lower()]
            cls.body = _Translator(self, name, cls).function(pou.implementation)

    def layout(self, name: str) -> Layout:
        t = self.types.get(name.lower())
        if isinstance(t, StructType) and t.layout is not None:
            return t.layout
        fields, pack = self._structs[self.types[name.lower()].name]
        return Layout(list(fields.items()), pack, self.layout)

    def default(self, t):
        if isinstance(t, Arr):
            return [self.default(t.base) for _ in range(t.upper - t.lower + 1)]
        if isinstance(t, Str):
            return ""
        if t == "BOOL":
            return False
        if t in REALS:
            return 0.0
        if t in SIZE or t == POINTER:
            return 0 if t != POINTER else None
        kind = self.types.get(t.lower())
        if isinstance(kind, StructType):
            return kind.new()
        if isinstance(kind, EnumType):
            return next(iter(kind.values.values()))
        return None                         # a block instance: made by `instance`

    def instance(self, name: str) -> Block:
        """A new instance of the block or program ``name``, its variables initialised."""
        cls = self.blocks[name.lower()]
        obj = cls.__new__(cls)
        obj._m = self
        for n, t in {**cls.INPUTS, **cls.OUTPUTS, **cls.LOCALS}.items():
            if isinstance(t, str) and t.lower() in self.blocks:
                setattr(obj, n, self.instance(t))
            else:
                setattr(obj, n, self.default(t))
        for n, v in getattr(cls, "INITS", {}).items():
            setattr(obj, n, v)
        return obj


class _Translator:
    """One POU's statements as the source of a Python function ``body(self)``."""

    def __init__(self, machine: Machine, name: str, cls):
        self.m, self.name, self.cls = machine, name, cls
        self.vars = {n.lower(): (n, t) for n, t in {**cls.INPUTS, **cls.OUTPUTS, **cls.LOCALS}.items()}
        self.lines: list[str] = []
        self.temps = 0

    def fail(self, node, why: str):
        line = getattr(getattr(node, "meta", None), "line", "?")
        raise StError(f"{self.name}: line {line}: {why}")

    def function(self, statements) -> Any:
        self.lines = ["def body(self):", "    rt = M.runtime"]
        self.block(statements, 1)
        self.lines.append("    return None")
        namespace = {**self.m.namespace, "M": self.m}
        exec("\n".join(self.lines), namespace)     # noqa: S102 (our own translation of the parsed source)
        body = namespace["body"]
        body.source = "\n".join(self.lines)
        return body

    def emit(self, depth: int, text: str) -> None:
        self.lines.append("    " * depth + text)

    def block(self, statements, depth: int) -> None:
        items = statements.statements if statements is not None else []
        if not items:
            self.emit(depth, "pass")
        for s in items:
            self.statement(s, depth)

    # -- statements ------------------------------------------------------------------------------------
    def statement(self, s, depth: int) -> None:
        if isinstance(s, tf.AssignmentStatement):
            value, vt = self.expr(s.expression)
            for target in s.variables:
                code, tt = self.access(target, store=True)
                self.store(depth, code, tt, value, vt, s)
        elif isinstance(s, tf.FunctionCallStatement):
            self.call_block(s, depth)
        elif isinstance(s, tf.IfStatement):
            self.emit(depth, f"if {self.condition(s.if_expression)}:")
            self.block(s.statements, depth + 1)
            for clause in s.else_ifs:
                self.emit(depth, f"elif {self.condition(clause.if_expression)}:")
                self.block(clause.statements, depth + 1)
            if s.else_clause is not None:
                self.emit(depth, "else:")
                self.block(s.else_clause.statements, depth + 1)
        elif isinstance(s, tf.CaseStatement):
            code, t = self.expr(s.expression)
            if t not in INTS and t != ANY_INT:
                self.fail(s, f"CASE on {t}: IEC takes an integer (or an enum's own values)")
            temp = self.temp()
            self.emit(depth, f"{temp} = {code}")
            word = "if"
            for case in s.cases:
                labels = []
                for match in case.matches:
                    label, lt = self.expr(match)
                    if common(lt, t) is None:
                        self.fail(case, f"CASE label of {lt} for a selector of {t}")
                    labels.append(label)
                self.emit(depth, f"{word} {temp} in ({', '.join(labels)},):")
                self.block(case.statements, depth + 1)
                word = "elif"
            if s.else_clause is not None:
                self.emit(depth, "else:" if word == "elif" else "if True:")
                self.block(s.else_clause.statements, depth + 1)
        elif isinstance(s, tf.ForStatement):
            var, vt = self.access(s.control, store=True)
            start, st = self.expr(s.from_)
            end, et = self.expr(s.to)
            step, pt = self.expr(s.step) if s.step is not None else ("1", ANY_INT)
            if vt not in INTS or any(common(x, vt) is None for x in (st, et, pt)):
                self.fail(s, "FOR takes an integer variable and integer bounds")
            self.emit(depth, f"{var} = {start}")
            self.emit(depth, f"while ({var} <= {end}) if ({step}) > 0 else ({var} >= {end}):")
            self.block(s.statements, depth + 1)
            self.emit(depth + 1, f"{var} = W_{vt}({var} + ({step}))")
        else:
            self.fail(s, f"{type(s).__name__} is outside the subset this machine runs")

    def temp(self) -> str:
        self.temps += 1
        return f"_t{self.temps}"

    def condition(self, node) -> str:
        code, t = self.expr(node)
        if t != "BOOL":
            self.fail(node, f"a condition of {t}: IEC takes BOOL")
        return code

    def store(self, depth: int, target: str, tt, value: str, vt, node) -> None:
        if not self.assignable(vt, tt):
            self.fail(node, f"{vt} assigned to {tt}: IEC 61131-3 converts it only explicitly")
        kind = self.m.types.get(tt.lower()) if isinstance(tt, str) else None
        if isinstance(kind, StructType):
            self.emit(depth, f"{target}.assign({value})")
        elif isinstance(tt, Arr):
            self.emit(depth, f"{target}[:] = {value}")
        elif tt in INTS or tt in BITS or tt == "TIME":
            self.emit(depth, f"{target} = W_{tt}({value})")
        elif tt == "REAL":
            self.emit(depth, f"{target} = f32({value})")
        elif tt == "LREAL":
            self.emit(depth, f"{target} = float({value})")
        elif isinstance(tt, Str):
            self.emit(depth, f"{target} = ({value})[:{tt.length}]")
        else:
            self.emit(depth, f"{target} = {value}")

    def assignable(self, src, dst) -> bool:
        if src == dst or (isinstance(src, str) and isinstance(dst, str) and widens(src, dst)):
            return True
        return isinstance(src, Str) and isinstance(dst, Str)

    def call_block(self, s, depth: int) -> None:
        code, t = self.access(s.name)
        cls = self.m.blocks.get(t.lower()) if isinstance(t, str) else None
        if cls is None:
            self.fail(s, f"{t} called as a statement: only function block instances are")
        pins = {n.lower(): (n, pt) for n, pt in cls.INPUTS.items()}
        obj = self.temp()
        self.emit(depth, f"{obj} = {code}")
        for p in s.parameters:
            if not isinstance(p, tf.InputParameterAssignment) or p.name is None:
                self.fail(s, "a block is called with named inputs (pin := value) only")
            pin = str(p.name.name).lower()
            if pin not in pins:
                self.fail(s, f"{t} has no input {p.name.name}")
            name, pt = pins[pin]
            value, vt = self.expr(p.value)
            self.store(depth, f"{obj}.{name}", pt, value, vt, s)
        self.emit(depth, f"{obj}.body()")

    # -- expressions -----------------------------------------------------------------------------------
    def expr(self, node) -> tuple[str, Any]:
        if isinstance(node, tf.Boolean):
            return ("True" if str(node.value).upper() == "TRUE" else "False"), "BOOL"
        if isinstance(node, tf.BitString):
            value = int(str(node.value).replace("_", ""), node.base)
            return str(value), (str(node.type_name).upper() if node.type_name else ANY_INT)
        if isinstance(node, tf.Integer):
            value = int(str(node.value).replace("_", ""), node.base)
            return str(value), (str(node.type_name).upper() if node.type_name else ANY_INT)
        if isinstance(node, tf.Real):
            return repr(float(str(node.value).replace("_", ""))), (str(node.type_name).upper() if node.type_name
                                                                   else ANY_REAL)
        if isinstance(node, tf.Duration):
            ms = sum(float(str(getattr(node, f) or 0)) * k for f, k in (("days", 86_400_000), ("hours", 3_600_000),
                                                                       ("minutes", 60_000), ("seconds", 1000),
                                                                       ("milliseconds", 1)))
            return str(int(-ms if node.negative else ms)), "TIME"
        if isinstance(node, tf.String):
            text = str(node.value)[1:-1]
            return repr(text), Str(len(text))
        if isinstance(node, tf.ParenthesizedExpression):
            code, t = self.expr(node.expr)
            return f"({code})", t
        if isinstance(node, tf.UnaryOperation):
            return self.unary(node)
        if isinstance(node, tf.BinaryOperation):
            return self.binary(node)
        if isinstance(node, tf.FunctionCall):
            return self.function_call(node)
        if isinstance(node, (tf.SimpleVariable, tf.MultiElementVariable)):
            return self.access(node)
        self.fail(node, f"{type(node).__name__} is outside the subset this machine runs")

    def unary(self, node) -> tuple[str, Any]:
        code, t = self.expr(node.expr)
        op = str(node.op).upper()
        if op == "NOT":
            if t == "BOOL":
                return f"(not {code})", t
            if t in BITS:
                return f"(~{code} & {(1 << BITS[t]) - 1})", t
            self.fail(node, f"NOT on {t}: IEC takes BOOL or a bit string (BYTE, WORD, DWORD, LWORD)")
        if op == "-":
            if t in INTS or t in REALS or t in (ANY_INT, ANY_REAL, "TIME"):
                return f"(-{code})", t
            self.fail(node, f"- on {t}")
        self.fail(node, f"unary {op}")

    def binary(self, node) -> tuple[str, Any]:
        a, at = self.expr(node.left)
        b, bt = self.expr(node.right)
        op = str(node.op).upper()
        if op in ("AND", "OR", "XOR", "AND_THEN", "OR_ELSE"):
            t = common(at, bt)
            if t == "BOOL":
                py = {"AND": "and", "AND_THEN": "and", "OR": "or", "OR_ELSE": "or", "XOR": "!="}[op]
                return f"({a} {py} {b})", t
            if t in BITS or (t == ANY_INT and {at, bt} & set(BITS)):
                py = {"AND": "&", "OR": "|", "XOR": "^"}[op]
                return f"({a} {py} {b})", t
            self.fail(node, f"{op} on {at} and {bt}: IEC takes BOOL or bit strings (BYTE, WORD, DWORD, LWORD)")
        if op in ("=", "<>", "<", ">", "<=", ">="):
            t = common(at, bt)
            enum = at == bt and isinstance(self.m.types.get(str(at).lower()), EnumType)
            if t is None and not enum:
                self.fail(node, f"{at} {op} {bt}: the operands' types differ")
            py = {"=": "==", "<>": "!="}.get(op, op)
            return f"({a} {py} {b})", "BOOL"
        if op in ("+", "-", "*", "/", "MOD"):
            t = common(at, bt)
            if t == "TIME" or (op in ("*", "/") and at == "TIME" and bt in (*INTS, ANY_INT)):
                t = "TIME"
            elif t is None or not (t in INTS or t in REALS or t in (ANY_INT, ANY_REAL)):
                self.fail(node, f"{at} {op} {bt}: arithmetic on different or non-numeric types")
            if op == "/":
                expr = f"idiv({a}, {b})" if (t in INTS or t in (ANY_INT, "TIME")) else f"({a} / {b})"
            elif op == "MOD":
                expr = f"({a} - idiv({a}, {b}) * {b})"
            else:
                expr = f"({a} {op} {b})"
            return (f"f32{expr}" if expr.startswith("(") else f"f32({expr})") if t == "REAL" else expr, t
        if op == "**":
            self.fail(node, "** is outside the subset")
        self.fail(node, f"operator {op}")

    def function_call(self, node) -> tuple[str, Any]:
        name = str(node.name.name) if isinstance(node.name, tf.SimpleVariable) else str(node.name)
        args = []
        for p in node.parameters:
            if not isinstance(p, tf.InputParameterAssignment) or p.name is not None:
                self.fail(node, f"{name}: a function takes its inputs by position here")
            args.append(p.value)
        upper = name.upper()
        m = re.fullmatch(r"([A-Z]+)_TO_([A-Z]+)", upper)
        if m:
            src, dst = m.groups()
            (code, t), = [self.expr(a) for a in args]
            if not (t == src or (t == ANY_INT and src in INTS | BITS) or (t == ANY_REAL and src in REALS)):
                self.fail(node, f"{name} of {t}: it takes {src}")
            if src in REALS and (dst in INTS or dst in BITS):
                return f"W_{dst}(rha({code}))", dst
            if dst in INTS or dst in BITS:
                return f"W_{dst}({code})", dst
            if dst == "REAL":
                return f"f32(float({code}))", dst
            if dst == "LREAL":
                return f"float({code})", dst
            self.fail(node, f"{name} is outside the subset")
        if upper in ("LIMIT", "MIN", "MAX"):
            got = [self.expr(a) for a in args]
            t = got[0][1]
            for _, at in got[1:]:
                t = common(t, at)
                if t is None:
                    self.fail(node, f"{name} of {[g[1] for g in got]}: the inputs' types differ")
            codes = [c for c, _ in got]
            if upper == "LIMIT":
                return f"min(max({codes[1]}, {codes[0]}), {codes[2]})", t
            return f"{upper.lower()}({', '.join(codes)})", t
        if upper == "ABS":
            (code, t), = [self.expr(a) for a in args]
            return f"abs({code})", t
        if upper == "ADR":
            code, t = self.access(args[0])
            return f"Pointer({code}, {t!r})", POINTER
        if upper == "GETCURTASKINDEXEX":
            return "1", "BYTE"
        self.fail(node, f"function {name} is outside the subset")

    def access(self, node, store: bool = False) -> tuple[str, Any]:
        """The Python code and the type of a variable (``x``, ``a[i]``, ``st.f``, ``GVL.c``, ``E.VALUE``)."""
        if isinstance(node, tf.SimpleVariable):
            base, elements = str(node.name), []
        elif isinstance(node, tf.MultiElementVariable):
            base, elements = str(node.name.name), list(node.elements)
        else:
            self.fail(node, f"{type(node).__name__} where a variable is expected")
        key = base.lower()
        if key in self.vars:
            name, t = self.vars[key]
            code = f"self.{name}"
        elif key in self.m.globals and elements and isinstance(elements[0], tf.FieldSelector):
            gvl, types, constants = self.m.globals[key]
            field = str(elements.pop(0).field.name)
            match = {n.lower(): n for n in types}.get(field.lower())
            if match is None:
                self.fail(node, f"{gvl} has no {field}")
            if store and match in constants:
                self.fail(node, f"{gvl}.{match} is a constant")
            code, t = f"G_{gvl}.{match}", types[match]
        elif isinstance(self.m.types.get(key), EnumType) and elements:
            enum = self.m.types[key]
            value = str(elements.pop(0).field.name)
            if value not in enum.values or store:
                self.fail(node, f"{enum.name}.{value}")
            code, t = str(enum.values[value]), enum.name
        else:
            self.fail(node, f"{base} is not declared (qualified_only lists are read as LIST.name)")
        for e in elements:
            if isinstance(e, tf.SubscriptList):
                if not isinstance(t, Arr) or len(e.subscripts) != 1:
                    self.fail(node, f"{base}: an index on {t}")
                index, it = self.expr(e.subscripts[0])
                if not (it in INTS or it in BITS or it == ANY_INT):
                    self.fail(node, f"{base}: an index of {it}")
                code, t = f"{code}[({index}) - {t.lower}]", t.base
            else:
                field = str(e.field.name)
                kind = self.m.types.get(t.lower()) if isinstance(t, str) else None
                if isinstance(kind, StructType):
                    fields = {n.lower(): n for n in kind.fields}
                    if field.lower() not in fields:
                        self.fail(node, f"{kind.name} has no field {field}")
                    name = fields[field.lower()]
                    code, t = f"{code}.{name}", kind.fields[name]
                elif isinstance(t, str) and t.lower() in self.m.blocks:
                    cls = self.m.blocks[t.lower()]
                    pins = {n.lower(): (n, pt) for n, pt in {**cls.INPUTS, **cls.OUTPUTS}.items()}
                    if field.lower() not in pins or (store and field.lower() not in
                                                     {n.lower() for n in cls.INPUTS}):
                        self.fail(node, f"{t}.{field}: not an input or output (or written from outside)")
                    name, pt = pins[field.lower()]
                    code, t = f"{code}.{name}", pt
                else:
                    self.fail(node, f"{base}: .{field} on {t}")
        return code, t


def load(paths, runtime: Runtime) -> Machine:
    """A machine running the TwinCAT sources ``paths`` (each parsed once per content, for the session:
    `plc_source.parse_file`)."""
    results = [r for p in sorted(paths) for r in parse_file(p)]
    packed = {Path(p).stem for p in paths if "{attribute 'pack_mode' := '1'}" in Path(p).read_text()}
    return Machine(CodeSummary.from_parse_results(results), packed, runtime)
