"""Fault bits, latching and the log line of each fault.

Every fault has one bit in the ``fault_word`` register. A fault latches: it stays set until the PLC
sends a reset (rising edge of command bit 2) and, if its cause is still there, trips again in the
next cycle. Each rising edge of a bit logs one line naming the fault and its cause.
"""

from __future__ import annotations

import logging

from .errors import (
    CanFrameError,
    SensorError,
    SensorSaturated,
    SensorStatusError,
    SensorTimeout,
    SensorValueError,
)

log = logging.getLogger("stiffcomp.faults")

FAULT_BITS = {
    "sensor_timeout": 0,      # the sensor silent past faults.sensor_timeout_ms
    "sensor_status": 1,       # the sensor's status word reports an error
    "sensor_saturated": 2,    # a gauge channel at the INT16 limit
    "value_invalid": 3,       # NaN, inf or out-of-range wrench, q or correction
    "can_frame": 4,           # a malformed or unknown CAN frame
    "plc_heartbeat": 5,       # the PLC heartbeat did not change within faults.plc_heartbeat_timeout_ms
    "overrun": 6,             # faults.overrun_trip_count consecutive cycles overran their period
    "joint_limits": 7,        # q outside the robot's joint limits
}

ERROR_FAULT = {
    SensorTimeout: "sensor_timeout",
    SensorStatusError: "sensor_status",
    SensorSaturated: "sensor_saturated",
    SensorValueError: "value_invalid",
    CanFrameError: "can_frame",
}


class FaultMonitor:
    """The latched fault word."""

    def __init__(self) -> None:
        self.word = 0
        self.trips = {name: 0 for name in FAULT_BITS}
        self.last_message: dict[str, str] = {}

    def trip(self, name: str, message: str) -> None:
        bit = 1 << FAULT_BITS[name]
        if not self.word & bit:
            self.word |= bit
            self.trips[name] += 1
            self.last_message[name] = message
            log.error("fault %s: %s; correction ramps to zero until reset", name, message)

    def trip_error(self, err: SensorError) -> None:
        self.trip(ERROR_FAULT.get(type(err), "value_invalid"), str(err))

    def reset(self) -> None:
        if self.word:
            log.warning("faults reset by the PLC (were: %s)", ", ".join(self.active()))
        self.word = 0

    def active(self) -> list[str]:
        return [n for n, b in FAULT_BITS.items() if self.word & (1 << b)]

    @property
    def faulted(self) -> bool:
        return self.word != 0
