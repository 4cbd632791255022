"""The one door between the ADS server and the process image (the cycle's shared memory)."""

from __future__ import annotations

from typing import Protocol

from plc_link.register_map import RegisterMap


class ImagePort(Protocol):
    """What the ADS server needs from the process image; `plc_link.image.ProcessImage` provides it."""

    rmap: RegisterMap

    def snapshot(self) -> tuple[int, int, list[int], list[int]]:
        """(version, stamp_ns, to_plc_words, from_plc_words) of one consistent cycle.

        ``version`` rises by one per published cycle; ``stamp_ns`` is ``time.time_ns()`` at that cycle's
        start (the FILETIME of the notifications).
        """
        ...

    def write(self, table: str, address: int, words: list[int]) -> bool:
        """A PLC write to the from_plc block (absolute Modbus address); False and no change if not allowed
        (not a PLC register, or starting or ending inside a 32-bit register)."""
        ...
