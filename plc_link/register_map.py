"""The register map (config/registers.yaml): names, addresses, types, and the block codecs.

Two blocks: ``to_plc`` (service -> PLC, input registers by default) and ``from_plc`` (PLC -> service,
holding registers, the only registers a client may write). 32-bit values take two registers, low
word first (TwinCAT's layout of a DINT/REAL over an ARRAY OF WORD); see docs/register_map.md.

Every register binds a name of the PLC contract (`plc_link.contract`) to an address; a name
the contract does not declare is refused, and so is a map that leaves out a required one. ``type``
defaults to the contract's type; an integer type with a ``scale`` may carry a float value.

`BlockCodec` packs a whole block with one `struct` call, which keeps the per-cycle cost small.
"""

from __future__ import annotations

import functools
import math
import operator
import re
import struct
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

from pydantic import Field, ValidationError

from stiffness.errors import StiffnessError, quote
from stiffness.files.yaml_schema import Strict, format_validation_error, read_yaml

from .contract import REQUIRED, VALUES
from .errors import RegisterMapError

TYPES = {"uint16": ("H", 1), "int16": ("h", 1), "uint32": ("I", 2), "int32": ("i", 2), "float32": ("f", 2)}
INT_RANGE = {"H": (0, 0xFFFF), "h": (-0x8000, 0x7FFF), "I": (0, 0xFFFFFFFF), "i": (-0x80000000, 0x7FFFFFFF)}
TABLES = ("input_registers", "holding_registers")


class RegisterEntry(Strict):
    name: str = Field(min_length=1)
    address: int = Field(ge=0, le=0xFFFF)
    type: Literal["uint16", "int16", "uint32", "int32", "float32"] | None = None
    unit: str = ""
    scale: float = Field(1.0, gt=0)
    description: str = ""


class BlockConfig(Strict):
    table: Literal["input_registers", "holding_registers"]
    start: int = Field(ge=0, le=0xFFFF)
    size: int = Field(ge=1, le=256)
    registers: list[RegisterEntry]


class MapConfig(Strict):
    word_order: Literal["low_word_first"] = "low_word_first"
    to_plc: BlockConfig
    from_plc: BlockConfig


@dataclass(frozen=True)
class Register:
    """One named value in the map."""

    name: str
    table: str
    address: int
    type: str
    count: int
    unit: str
    scale: float
    direction: str
    description: str = ""

    def as_dict(self) -> dict:
        return {"name": self.name, "table": self.table, "address": self.address, "type": self.type,
                "count": self.count, "unit": self.unit, "scale": self.scale, "direction": self.direction}


class BlockCodec:
    """Pack the values of one block into its words and back, in the block's register order.

    Parameters
    ----------
    registers : list of Register, sorted by address
    start, size : the block's first address and its number of words
    """

    def __init__(self, registers: list[Register], start: int, size: int):
        self.names = [r.name for r in registers]
        self.start, self.size = start, size
        self.index = {n: k for k, n in enumerate(self.names)}
        fmt, pos = "<", start
        self._ints = []       # (index, scale, lo, hi) of the integer registers
        for k, r in enumerate(registers):
            code, count = TYPES[r.type]
            fmt += "xx" * (r.address - pos) + code
            pos = r.address + count
            if code != "f":
                self._ints.append((k, r.scale, *INT_RANGE[code]))
        self.words = pos - start
        self._struct = struct.Struct(fmt)
        self._words = struct.Struct("<" + "H" * self.words)
        self._scales = [r.scale for r in registers]
        self._unscaled = all(s == 1.0 for s in self._scales)
        self.pick = operator.attrgetter(*self.names) if len(self.names) > 1 else (
            lambda rec: (getattr(rec, self.names[0]),))

    def fields(self) -> list[tuple[str, int, float]]:
        """(struct code, byte offset from the block's start, scale) of each register, in ``names`` order: the
        layout `pack_into` writes (a compiled packer reads it, `service.kernel.pack`)."""
        return [(code, offset, scale) for (code, offset), scale in zip(struct_fields(self._struct.format),
                                                                        self._scales)]

    def encode_record(self, record) -> list[int]:
        """Words for a contract record (`ToPlc`, `FromPlc`): each register takes its value by name."""
        return self.encode(self.pick(record))

    def record_reader(self, record_type, optional: frozenset[str] = frozenset()):
        """A function values (``names`` order) -> ``record_type`` (a contract NamedTuple): each field by name.

        Every field of the record must be a register of the block, but for the ``optional`` ones, which
        the map may leave out: they read 0."""
        missing = [f for f in record_type._fields if f not in self.index and f not in optional]
        if missing:
            raise RegisterMapError(f"the block has no register {missing[0]!r} ({record_type.__name__} needs it)")
        zero = len(self.names)                  # the index of the 0 appended for the fields left out
        order = [self.index.get(f, zero) for f in record_type._fields]
        make = record_type._make
        if order == list(range(zero)):          # the map's order is the record's: the values as they are
            return functools.partial(tuple.__new__, record_type)     # (_make, without its Python frame)
        if all(k < zero for k in order):
            return lambda values: make(map(values.__getitem__, order))
        return lambda values: make(map([*values, 0.0].__getitem__, order))

    def encode(self, values: list[float]) -> list[int]:
        """Words for ``values`` given in ``names`` order (integers are scaled, rounded and clamped)."""
        return list(self._words.unpack(self._struct.pack(*self._scaled(values))))

    def _scaled(self, values) -> list:
        out = list(values)
        for k, scale, lo, hi in self._ints:
            x = out[k]
            if scale == 1 and x.__class__ is int and lo <= x <= hi:
                continue                # a counter or a word in range, as the cycle publishes them: as it is
            x = x * scale
            out[k] = min(max(round(x), lo), hi) if math.isfinite(x) else 0
        return out

    def pack_into(self, buffer, offset: int, values) -> None:
        """Write ``values`` (``names`` order) as the block's words, little-endian, into ``buffer`` at byte
        ``offset`` (the process image's memory: one struct call, no intermediate list of words)."""
        self._struct.pack_into(buffer, offset, *self._scaled(values))

    def unpack_from(self, buffer, offset: int) -> Sequence[float]:
        """Values in ``names`` order from the block's words in ``buffer`` at byte ``offset``."""
        raw = self._struct.unpack_from(buffer, offset)
        if self._unscaled:
            return raw
        return [v if s == 1.0 else v / s for v, s in zip(raw, self._scales)]

    def unpacker(self):
        """`unpack_from` itself, or where no register is scaled, the struct's own (one C call, a tuple)."""
        return self._struct.unpack_from if self._unscaled else self.unpack_from

    def decode(self, words: list[int]) -> list[float]:
        """Values in ``names`` order from the block's words (integers divided by their scale)."""
        raw = self._struct.unpack(self._words.pack(*words[: self.words]))
        return [v if s == 1.0 else v / s for v, s in zip(raw, self._scales)]


def struct_fields(fmt: str) -> list[tuple[str, int]]:
    """(code, byte offset) of each field of a little-endian `struct` format without alignment ("<": codes with
    optional counts, "x" pads), e.g. ``"<d2fxxH"`` -> [("d", 0), ("f", 8), ("f", 12), ("H", 18)]."""
    if not fmt.startswith("<"):
        raise ValueError(f"struct format {fmt!r}: only '<' (little-endian, no alignment) is read")
    out, offset = [], 0
    for count, code in re.findall(r"(\d*)([a-zA-Z?])", fmt[1:]):
        size = struct.calcsize("<" + code)
        for _ in range(int(count or 1)):
            if code != "x":
                out.append((code, offset))
            offset += size
    return out


class RegisterMap:
    """The validated map: registers by name, and one codec per direction."""

    def __init__(self, cfg: MapConfig, source: str = "<registers>"):
        self.source = source
        self._cfg = cfg
        self.blocks = {"to_plc": cfg.to_plc, "from_plc": cfg.from_plc}
        self.registers: list[Register] = []
        for direction, block in self.blocks.items():
            regs = sorted(block.registers, key=lambda r: r.address)
            used: dict[int, str] = {}
            declared = VALUES[direction]
            for k, r in enumerate(block.registers):
                where = f"{source}: {direction}.registers[{k}] ({r.name})"
                if r.name not in declared:
                    raise RegisterMapError(f"{where}: {quote(r.name)} is not a value the service produces for this "
                                           f"direction (the contract's {direction} values: {', '.join(declared)})")
                if r.type is None:
                    r.type = declared[r.name].type
                count = TYPES[r.type][1]
                if not (block.start <= r.address and r.address + count <= block.start + block.size):
                    raise RegisterMapError(f"{where}: address = {r.address:#06x} must lie in "
                                           f"[{block.start:#06x}, {block.start + block.size - count:#06x}]")
                for a in range(r.address, r.address + count):
                    if a in used:
                        raise RegisterMapError(f"{where}: address = {r.address:#06x} overlaps {used[a]}")
                    used[a] = r.name
                if r.type == "float32" and r.scale != 1.0:
                    raise RegisterMapError(f"{where}: scale = {r.scale:g}: float32 registers take scale 1")
            for r in regs:      # unit and meaning default to the contract's
                v = declared[r.name]
                self.registers.append(Register(r.name, block.table, r.address, r.type, TYPES[r.type][1],
                                               r.unit or v.unit, r.scale, direction, r.description or v.meaning))
            names = [r.name for r in block.registers]
            dup = sorted({n for n in names if names.count(n) > 1})
            if dup:
                raise RegisterMapError(f"{source}: {direction}: register name {quote(dup[0])} appears twice")
            missing = [n for n in REQUIRED[direction] if n not in names]
            if missing:
                raise RegisterMapError(f"{source}: {direction}: register {quote(missing[0])} is missing "
                                       f"(needed: {', '.join(REQUIRED[direction])})")
        if cfg.from_plc.table != "holding_registers":
            raise RegisterMapError(f"{source}: from_plc.table = {quote(cfg.from_plc.table)}: the PLC can write only "
                                   "holding_registers")
        a, b = cfg.to_plc, cfg.from_plc
        if a.table == b.table and a.start < b.start + b.size and b.start < a.start + a.size:
            raise RegisterMapError(
                f"{source}: to_plc [{a.start:#06x}, {a.start + a.size:#06x}) and from_plc [{b.start:#06x}, "
                f"{b.start + b.size:#06x}) overlap in {a.table}: the PLC's writes would land in the service's block")
        self.by_name = {r.name: r for r in self.registers}
        self.codecs = {d: BlockCodec([r for r in self.registers if r.direction == d], b.start, b.size)
                       for d, b in self.blocks.items()}
        self.writable = {a for r in self.registers if r.direction == "from_plc"
                         for a in range(r.address, r.address + r.count)}

    def __reduce__(self):
        """Pickled as its validated config (the compiled codecs are rebuilt): for the server process."""
        return (RegisterMap, (self._cfg, self.source))

    @classmethod
    def from_yaml(cls, path: str | Path) -> RegisterMap:
        try:
            data = read_yaml(path)
        except StiffnessError as e:
            raise RegisterMapError(str(e)) from e
        try:
            cfg = MapConfig.model_validate(data)
        except ValidationError as e:
            raise RegisterMapError(format_validation_error(str(path), e)) from e
        return cls(cfg, str(path))

    def extended(self, names) -> dict:
        """The map's config (a mapping, as its YAML holds it) with the from-PLC values ``names`` bound one after
        another from the end of its last from-PLC register, each as the contract types it (no gap: a PLC writes
        its block whole; docs/register_map.md). RegisterMapError for a name the PLC does not write or one the map
        binds already."""
        data = self._cfg.model_dump(exclude_none=True)
        at = max(r.address + r.count for r in self.registers if r.direction == "from_plc")
        for name in names:
            if name not in VALUES["from_plc"] or name in self.by_name:
                raise RegisterMapError(f"{self.source}: cannot add {quote(name)}: "
                                       + ("the map binds it already" if name in self.by_name else
                                          "it is not a value the PLC writes"))
            kind = VALUES["from_plc"][name].type
            data["from_plc"]["registers"].append({"name": name, "address": at, "type": kind})
            at += TYPES[kind][1]
        return data

    def as_list(self) -> list[dict]:
        """The map as `stiffcomp registers --json` prints it."""
        return [r.as_dict() for r in self.registers]
