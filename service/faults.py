"""The latched fault word and the log line of each fault.

Every fault has one bit in ``fault_word`` (`plc_link.contract.Fault`). A fault latches: it stays
set until the PLC sends a reset (rising edge of `Command.RESET`) and, if its cause is still there,
trips again in the next cycle. Each rising edge of a bit logs one line naming the fault and its cause.
A sensor error names its own fault (`SensorError.fault`): no table maps error types to bits.
"""

from __future__ import annotations

import logging

from plc_link.contract import Fault

from .errors import SensorError

log = logging.getLogger("stiffcomp.faults")


class FaultMonitor:
    """The latched fault word, with a trip count and the last message per fault kind."""

    def __init__(self, commander: str = "the PLC") -> None:
        self.commander = commander          # who writes the command word: "the PLC", or the robot on its road
        self.word = 0
        self.trips = {f.kind: 0 for f in Fault}
        self.last_message: dict[str, str] = {}

    def trip(self, fault: Fault, message: str) -> None:
        if not self.word & fault:
            self.word |= int(fault)
            self.trips[fault.kind] += 1
            self.last_message[fault.kind] = message
            log.error("fault %s: %s; correction ramps to zero until reset", fault.kind, message)

    def trip_error(self, err: SensorError) -> None:
        self.trip(err.fault, str(err))

    def reset(self) -> None:
        if self.word:
            log.warning("faults reset by %s (were: %s)", self.commander, ", ".join(self.active()))
        self.word = 0

    def active(self) -> list[str]:
        return Fault.spell(self.word)
