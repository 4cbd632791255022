"""Supervision beside the signal path: command edges, the PLC heartbeat, overruns and the joint limits.

As Klipper's ``verify_heater`` watches a heater beside its control loop, `Supervisor.update` watches
the cycle's inputs and decides, each cycle, whether the correction may be applied; the signal path
(`service.pipeline.Compensator`) only computes. Faults latch in the shared `FaultMonitor`:

* reset (rising edge of `Command.RESET`) clears them first, so a fault whose cause persists trips again
  in the same cycle (the sensor errors of the cycle are applied after the reset);
* the PLC heartbeat must change within ``heartbeat_timeout_s`` while the PLC enables (supervision
  starts at the enable's rising edge; 0 switches it off);
* ``overrun_trip_count`` consecutive exceeded cycles trip the overrun fault;
* a joint position from the PLC that is not finite or outside the robot's limits trips a fault, and
  the kinematics keep the last good one;
* a command word that sets a bit the contract does not define (`COMMAND_BITS`) trips
  ``command_invalid`` and is not acted on at all: no enable, no tare, no reset, and no edge when a valid
  word follows it (0xFFFF, then 0x0007 tares nothing);
* a fault held by the service from outside the cycle (`Supervisor.held`, e.g. ``io_process`` while the
  I/O process is down) trips every cycle, after a reset, as a sensor error does.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from pydantic import Field

from plc_link.contract import COMMAND_BITS, Command, Fault
from stiffness.files.yaml_schema import Strict

from .cycle_rules import heartbeat, heartbeat_late
from .errors import SensorError
from .faults import FaultMonitor

# the command bits as plain ints: IntFlag arithmetic costs microseconds in a 1 ms cycle
_ENABLE, _TARE, _RESET = int(Command.ENABLE), int(Command.TARE), int(Command.RESET)
_UNDEFINED = ~COMMAND_BITS


class FaultsConfig(Strict):
    """``faults``: when the sensor, the PLC's heartbeat and exceeded cycles trip a fault (the sensor
    timeout is read by the sources; both longer than the cycle, checked with ``cycle``)."""

    sensor_timeout_ms: float = Field(10.0, gt=0)
    plc_heartbeat_timeout_ms: float = Field(200.0, ge=0)
    overrun_trip_count: int = Field(10, ge=1, le=1000)
    io_restarts: int = Field(3, ge=0, le=100)


class Supervision(NamedTuple):
    """What the supervisor decided for one cycle."""

    enabled: bool                   # the PLC enables (or enable_on_start)
    tare: bool                      # rising edge of the tare bit
    reset: bool                     # rising edge of the reset bit
    q_deg: list[float] | None       # new, valid joint positions (None: unchanged or refused)


_QUIET = (Supervision(False, False, False, None), Supervision(True, False, False, None))


class Supervisor:
    """Watch the commands, the heartbeat, overruns and the joints.

    Parameters
    ----------
    faults : FaultMonitor
    joint_limits_deg : (6, 2)
    heartbeat_timeout_s : float
        0 switches the PLC heartbeat supervision off.
    overrun_trip_count : int
    enable_on_start : bool
        Act as if the enable bit were set (demo and bench without a PLC).
    """

    def __init__(self, faults: FaultMonitor, joint_limits_deg: np.ndarray, heartbeat_timeout_s: float,
                 overrun_trip_count: int, enable_on_start: bool = False):
        self.faults = faults
        self.lo = [float(v) for v in joint_limits_deg[:, 0]]
        self.hi = [float(v) for v in joint_limits_deg[:, 1]]
        self.hb_timeout = float(heartbeat_timeout_s)
        self.overrun_trip = int(overrun_trip_count)
        self.enable_on_start = enable_on_start
        self.prev_command = 0
        self.prev_hb = math.nan                 # the last heartbeat read (NaN: none yet)
        self.hb_change_t = 0.0
        self.plc_seen = False
        self.overruns = 0
        self._q_last: list[float] | None = None
        # faults whose cause lives outside the cycle, replaced whole by another thread (never mutated)
        self.held: tuple[tuple[Fault, str], ...] = ()

    @classmethod
    def from_config(cls, section: FaultsConfig, faults: FaultMonitor, joint_limits_deg: np.ndarray,
                    enable_on_start: bool) -> Supervisor:
        """From the ``faults`` section; ``enable_on_start`` is the PLC's (``plc.enable_on_start``)."""
        return cls(faults, joint_limits_deg, section.plc_heartbeat_timeout_ms / 1000.0,
                   section.overrun_trip_count, enable_on_start)

    def update(self, t: float, command: int, plc_heartbeat: int, q_deg: list[float], overrun: bool,
               errors: list[SensorError]) -> Supervision:
        """One cycle at ``t`` (s)."""
        faults = self.faults
        undefined = command & _UNDEFINED
        rising = 0 if undefined else command & ~self.prev_command
        self.prev_command = command
        if undefined:
            command = 0
        reset = rising & _RESET != 0
        if reset:
            faults.reset()
            self.overruns = 0
        # after the reset: a reset clears only faults whose cause is gone
        if undefined:
            faults.trip(Fault.COMMAND_INVALID, f"command_word = 0x{self.prev_command:04X} sets undefined bit(s) "
                        f"{', '.join(str(b) for b in range(16) if undefined >> b & 1)} (defined: 0 enable, "
                        "1 tare, 2 reset); the word is ignored")
        for fault, message in self.held:
            faults.trip(fault, message)
        for e in errors:
            faults.trip_error(e)
        if plc_heartbeat != self.prev_hb or rising & _ENABLE or (self.hb_timeout > 0 and command & _ENABLE):
            self._heartbeat(t, plc_heartbeat, rising & _ENABLE != 0, command & _ENABLE != 0)
        if overrun:
            self.overruns += 1
            if self.overruns >= self.overrun_trip:
                faults.trip(Fault.OVERRUN, f"{self.overruns} consecutive cycles overran their period")
        else:
            self.overruns = 0
        enabled = command & _ENABLE != 0 or self.enable_on_start
        if q_deg != self._q_last and self._check_q(q_deg):
            # exact comparison: a cache that never approximates
            self._q_last = list(q_deg)
            return Supervision(enabled, rising & _TARE != 0, reset, self._q_last)
        if rising & _TARE or reset:
            return Supervision(enabled, rising & _TARE != 0, reset, None)
        return _QUIET[enabled]          # most cycles: nothing new (one of two records, not a new one)

    def _check_q(self, q_deg: list[float]) -> bool:
        for j, v in enumerate(q_deg):
            if not math.isfinite(v):
                self.faults.trip(Fault.VALUE_INVALID, f"q{j + 1} = {v} from the PLC is not finite")
                return False
            if not self.lo[j] <= v <= self.hi[j]:
                self.faults.trip(Fault.JOINT_LIMITS, f"q{j + 1} = {v:.3f} deg is outside the joint limits "
                                 f"[{self.lo[j]:g}, {self.hi[j]:g}]")
                return False
        return True

    def heartbeat_seen(self, t: float, hb: int) -> None:
        """The PLC's heartbeat ``hb`` at ``t`` (s): a change restarts its timeout, and the first change says the
        PLC is there (`service.kernel.glue.heartbeat`)."""
        self.prev_hb, self.hb_change_t, self.plc_seen = heartbeat(self.prev_hb, self.hb_change_t, self.plc_seen,
                                                                  float(hb), t, False)

    def _heartbeat(self, t: float, hb: int, enable_rose: bool, enabled_by_plc: bool) -> None:
        # supervision starts when the PLC enables (the rising edge restarts the timeout too)
        self.prev_hb, self.hb_change_t, self.plc_seen = heartbeat(self.prev_hb, self.hb_change_t, self.plc_seen,
                                                                  float(hb), t, enable_rose)
        if heartbeat_late(self.hb_timeout, enabled_by_plc, t, self.hb_change_t):
            self.faults.trip(Fault.PLC_HEARTBEAT, f"plc_heartbeat of {self.faults.commander} unchanged for "
                             f"{(t - self.hb_change_t) * 1000:.0f} ms (timeout {self.hb_timeout * 1000:g} ms)")
