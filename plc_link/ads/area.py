"""The ADS data areas over the process image: %MB (index group 0x4020), the task info (0x4040), the PLC
runtime's state (0xF100) and the symbol version (0xF008).

%MB lays the Modbus words end to end, as TF6250 lays its registers over the PLC's memory: the to_plc
block's words first, then the from_plc block's, each word little-endian. The register at word index
``w`` of that concatenation sits at byte offset ``2 * w``, so a float32 register (two words, low word
first) reads as a REAL and a uint32 as a UDINT (docs/ads.md).

The task info is read-only and computed on read from the to_plc values, in TwinCAT's units (100 ns).
The runtime state is what ReadState answers, as TwinCAT's 0xF100 is: the ADS state (from
``task_state``) and the device state, a UINT each. The symbol version is one byte (`Device.symbol_version`).
All four can be read and subscribed, none written.
"""

from __future__ import annotations

import math
import struct

from plc_link.register_map import Register, RegisterMap

from . import ams

MB_GROUP = 0x4020
TASKINFO_GROUP = 0x4040
STATE_GROUP = 0xF100                # ADSIGRP_DEVICE_DATA: ADS state, device state
SYMVER_GROUP = 0xF008               # ADSIGRP_SYM_VERSION
GROUPS = (MB_GROUP, TASKINFO_GROUP, STATE_GROUP, SYMVER_GROUP)
STATE = struct.Struct("<HH")
TASK_STATES = {0: ams.ADSSTATE_INIT, 1: ams.ADSSTATE_RUN, 2: ams.ADSSTATE_STOP}   # task_state -> ADS state
TASKINFO = struct.Struct("<IIIB3xI")
# name, TwinCAT type, offset in TASKINFO, the to_plc value it comes from, factor to TwinCAT's unit
TASKINFO_FIELDS = (
    ("CycleTime", "UDINT", 0, "cycle_time_us", 10.0),       # µs -> 100 ns
    ("CycleCount", "UDINT", 4, "cycle_count", 1.0),
    ("LastExecTime", "UDINT", 8, "last_exec_us", 10.0),
    ("CycleTimeExceeded", "BOOL", 12, "cycle_exceeded", 1.0),
    ("ExceedCounter", "UDINT", 16, "exceed_count", 1.0),
)


class Layout:
    """Byte offsets of the registers in %MB, and which byte spans a client may write.

    Parameters
    ----------
    rmap : the register map; its blocks' sizes fix the area's size
    """

    def __init__(self, rmap: RegisterMap):
        self.rmap = rmap
        self.to_block, self.from_block = rmap.blocks["to_plc"], rmap.blocks["from_plc"]
        self.mb_size = 2 * (self.to_block.size + self.from_block.size)
        self.codec = rmap.codecs["to_plc"]
        # [start, end) byte spans of the PLC's registers: a write must cover whole spans
        self.spans = sorted((self.mb_offset(r), self.mb_offset(r) + 2 * r.count)
                            for r in rmap.registers if r.direction == "from_plc")
        self.starts = {a for a, _ in self.spans}
        self.ends = {b for _, b in self.spans}
        self.writable = {o for a, b in self.spans for o in range(a, b)}

    def mb_offset(self, r: Register) -> int:
        """Byte offset of register ``r`` in %MB."""
        if r.direction == "to_plc":
            return 2 * (r.address - self.to_block.start)
        return 2 * (self.to_block.size + r.address - self.from_block.start)

    def check_write(self, offset: int, length: int) -> int:
        """0 if %MB bytes [offset, offset + length) are whole PLC registers, else the ADS error."""
        if offset >= self.mb_size:
            return ams.ADSERR_INVALID_OFFSET
        if length == 0 or offset + length > self.mb_size:
            return ams.ADSERR_INVALID_SIZE
        if any(o not in self.writable for o in range(offset, offset + length)):
            return ams.ADSERR_INVALID_ACCESS
        if offset not in self.starts or offset + length not in self.ends:
            return ams.ADSERR_INVALID_SIZE      # half of a 32-bit register
        return 0

    def write(self, port, offset: int, data: bytes) -> int:
        """Write %MB bytes through ``port``; the ADS result code."""
        err = self.check_write(offset, len(data))
        if err:
            return err
        words = list(struct.unpack(f"<{len(data) // 2}H", data))
        address = self.from_block.start + offset // 2 - self.to_block.size
        return 0 if port.write(self.from_block.table, address, words) else ams.ADSERR_INVALID_ACCESS


class AreaView:
    """The readable areas of one snapshot (one cycle), built once and read by many requests.

    Parameters
    ----------
    layout : Layout
    snap : (version, stamp_ns, to_plc_words, from_plc_words) from `ImagePort.snapshot`
    symbol_version : the byte 0xF008 answers
    """

    def __init__(self, layout: Layout, snap: tuple[int, int, list[int], list[int]], symbol_version: int = 1):
        self.layout, self.symbol_version = layout, symbol_version
        self.version, self.stamp_ns, self._to, self._from = snap
        self._mb: bytes | None = None
        self._task: bytes | None = None

    @property
    def mb(self) -> bytes:
        if self._mb is None:
            lay = self.layout
            to = list(self._to[: lay.to_block.size]) + [0] * max(0, lay.to_block.size - len(self._to))
            fr = list(self._from[: lay.from_block.size]) + [0] * max(0, lay.from_block.size - len(self._from))
            self._mb = struct.pack(f"<{len(to) + len(fr)}H", *to, *fr)
        return self._mb

    def values(self) -> dict[str, float]:
        """The to_plc values by name."""
        codec = self.layout.codec
        words = list(self._to[: codec.words])
        words += [0] * (codec.words - len(words))
        return dict(zip(codec.names, codec.decode(words)))

    @property
    def task(self) -> bytes:
        if self._task is None:
            v = self.values()
            fields = [_udint(v.get(src, 0.0) * factor) for _, _, _, src, factor in TASKINFO_FIELDS]
            fields[3] = 1 if fields[3] else 0
            self._task = TASKINFO.pack(*fields)
        return self._task

    @property
    def ads_state(self) -> int:
        """The runtime's ADS state (ReadState, 0xF100): RUN unless the cycle reports INIT or STOP."""
        return TASK_STATES.get(int(self.values().get("task_state", 1)), ams.ADSSTATE_RUN)

    def read(self, group: int, offset: int, length: int) -> tuple[int, bytes]:
        """(ADS result, data) of reading ``length`` bytes at ``group``/``offset``."""
        if group == MB_GROUP:
            area = self.mb
        elif group == TASKINFO_GROUP:
            area = self.task
        elif group == STATE_GROUP:
            area = STATE.pack(self.ads_state, 0)
        elif group == SYMVER_GROUP:
            area = bytes([self.symbol_version])
        else:
            return ams.ADSERR_INVALID_GROUP, b""
        if offset >= len(area):
            return ams.ADSERR_INVALID_OFFSET, b""
        if offset + length > len(area):
            return ams.ADSERR_INVALID_SIZE, b""
        return 0, area[offset: offset + length]


def _udint(x: float) -> int:
    """A value as UDINT: rounded, clamped to 0..2**32-1; NaN as 0."""
    return min(max(round(x), 0), 0xFFFFFFFF) if math.isfinite(x) else 0
