"""IEC 61131-3's standard function blocks the runtime provides (TON, TP, R_TRIG), and the base of every block
instance: its variables as attributes, ``body`` runs one call."""

from __future__ import annotations

from typing import Any, ClassVar


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


