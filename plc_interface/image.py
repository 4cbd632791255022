"""The register image shared by the cycle thread and the Modbus side, guarded by one lock.

The cycle writes the whole ``to_plc`` block and reads the whole ``from_plc`` block once per cycle,
each under the lock, so a client never sees half of a 32-bit value from one cycle and half from the
next. Modbus access checks every address: reads must fall inside a block, writes inside the PLC's
registers (``from_plc``), covering every register they touch whole (no half of a 32-bit value);
anything else is refused with ILLEGAL_ADDRESS (0x02) and changes nothing.
"""

from __future__ import annotations

import threading
import time

from .register_map import RegisterMap

FC_TABLE = {3: "holding_registers", 4: "input_registers", 6: "holding_registers", 16: "holding_registers",
            23: "holding_registers"}


class RegisterImage:
    """Words of both blocks; addresses are absolute Modbus addresses."""

    def __init__(self, rmap: RegisterMap):
        self.map = self.rmap = rmap
        self.lock = threading.Lock()
        self.blocks = {}
        for direction, b in rmap.blocks.items():
            self.blocks[direction] = (b.table, b.start, [0] * b.size)
        self.by_table: dict[str, list[tuple[int, list[int]]]] = {}
        for table, start, words in self.blocks.values():
            self.by_table.setdefault(table, []).append((start, words))
        self.writable = rmap.writable
        # the second and later words of every multi-word PLC register: a write may neither start nor
        # end (exclusive end) there, or the cycle would read a value torn between two writes
        self.inner = {a for r in rmap.registers if r.direction == "from_plc"
                      for a in range(r.address + 1, r.address + r.count)}
        self.out_codec = rmap.codecs["to_plc"]
        self.in_codec = rmap.codecs["from_plc"]
        self.refused_writes = 0
        self.version, self.stamp_ns = 0, 0      # of the last publish (`snapshot`)

    # -- the cycle's side -----------------------------------------------------------------------
    def publish(self, words: list[int], stamp_ns: int | None = None) -> None:
        """Replace the to_plc block's leading words; ``stamp_ns`` is the cycle's start (time.time_ns)."""
        block = self.blocks["to_plc"][2]
        stamp = time.time_ns() if stamp_ns is None else stamp_ns
        with self.lock:
            block[: len(words)] = words
            self.version += 1
            self.stamp_ns = stamp

    def snapshot(self) -> tuple[int, int, list[int], list[int]]:
        """(version, stamp_ns, to_plc words, from_plc words) of one publish, for the ADS server."""
        to_plc, from_plc = self.blocks["to_plc"][2], self.blocks["from_plc"][2]
        with self.lock:
            return self.version, self.stamp_ns, list(to_plc), list(from_plc)

    def inputs(self) -> list[int]:
        """A consistent copy of the from_plc block."""
        block = self.blocks["from_plc"][2]
        with self.lock:
            return block[: self.in_codec.words]

    def set_inputs(self, values: dict[str, float]) -> None:
        """Set named from_plc values (initial joint positions; the client role's PLC reads)."""
        block = self.blocks["from_plc"][2]
        with self.lock:
            current = self.in_codec.decode(block)
            merged = [values.get(n, v) for n, v in zip(self.in_codec.names, current)]
            block[: self.in_codec.words] = self.in_codec.encode(merged)

    def outputs(self) -> dict[str, float]:
        """The to_plc values by name (for logs and tests)."""
        block = self.blocks["to_plc"][2]
        with self.lock:
            words = block[: self.out_codec.words]
        return dict(zip(self.out_codec.names, self.out_codec.decode(words)))

    # -- the Modbus side ------------------------------------------------------------------------
    def read(self, table: str, address: int, count: int) -> list[int] | None:
        """Words at [address, address + count) of ``table``, or None if outside every block."""
        for start, words in self.by_table.get(table, ()):
            if start <= address and address + count <= start + len(words):
                with self.lock:
                    return words[address - start: address - start + count]
        return None

    def write(self, table: str, address: int, values: list[int]) -> bool:
        """Write the PLC's registers; False (and no change) if any word is not the PLC's to write, or the
        write starts or ends inside a multi-word register."""
        end = address + len(values)
        if (table != "holding_registers" or any(a not in self.writable for a in range(address, end))
                or address in self.inner or end in self.inner):
            self.refused_writes += 1
            return False
        for start, words in self.by_table[table]:
            if start <= address and address + len(values) <= start + len(words):
                with self.lock:
                    words[address - start: address - start + len(values)] = [int(v) & 0xFFFF for v in values]
                return True
        self.refused_writes += 1
        return False
