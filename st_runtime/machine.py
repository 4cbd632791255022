"""The POUs, types and global lists of a set of TwinCAT sources, translated once and ready to run: `load`
gives a `Machine`; `Machine.instance("MAIN")` a program whose ``body()`` is one cycle of it."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from blark import transform as tf
from blark.summary import CodeSummary

from .blocks import R_TRIG, TON, TP, Block
from .requests import REQUESTS
from .source import parse_file
from .translate import Translator
from .values import (
    BITS,
    INTS,
    POINTER,
    REALS,
    SIZE,
    Arr,
    EnumType,
    Layout,
    Pointer,
    StError,
    Str,
    StructType,
    f32,
    parse_type,
    wrap,
)

LIBRARY = {"TON": TON, "TP": TP, "R_TRIG": R_TRIG, **REQUESTS}
# TwinCAT's task info (Tc2_System PlcTaskSystemInfo), the fields a program reads
TASK_INFO = {"CycleTime": "UDINT", "CycleCount": "UDINT", "LastExecTime": "UDINT"}


class Runtime:
    """The PLC's runtime: its clock (``now_ms``, set by whoever runs the task: a test's simulated time or the
    HIL's program time), its task's cycle time, and the `requests.Network` the request blocks use."""

    def __init__(self, network, cycle_ms: int = 1):
        self.now_ms = 0
        self.cycle_ms = cycle_ms
        self.network = network


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
        self.namespace: dict[str, Any] = {"f32": f32, "Pointer": Pointer, "Arr": Arr, "Str": Str, "StError": StError,
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
            cls.body = Translator(self, name, cls).function(pou.implementation)

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


def load(paths, runtime: Runtime) -> Machine:
    """A machine running the TwinCAT sources ``paths`` (each parsed once per content, for the session:
    `source.parse_file`)."""
    results = [r for p in sorted(paths) for r in parse_file(p)]
    packed = {Path(p).stem for p in paths if "{attribute 'pack_mode' := '1'}" in Path(p).read_text()}
    return Machine(CodeSummary.from_parse_results(results), packed, runtime)
