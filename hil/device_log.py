"""The logs the HIL's virtual devices leave, one declared type per device kind: the PLC's (`PlcLog`, written by
`hil.plc_process` and by the lock step) and the robot's (`RobotLog`, written by `hil.robot_process`).

Both are a `Track`, per cycle the time and the programmed and commanded joints: what the robot stub moves the
robot by (`hil.report.evaluate`) and what the end-to-end delay is fitted on (`hil.report.end_to_end_delay`).
Both are a `DeviceLog` too: the correction each cycle applied, the device's period, start time and overruns,
and the counts the report gives per pass (`DeviceLog.counts`). Each adds what only its device has, named by
what it is; which device ran is the log's type.

A child process writes its log with `save` (one ``.npz``, an array per field) and the parent reads it back with
the same type's `load`.
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import ClassVar

import numpy as np

_SCALARS = {"int": int, "float": float}      # a field of these types is stored as a 0-d array


@dataclass(frozen=True, eq=False)
class Track:
    """Per cycle: its time (s of program time: 0 when the cut starts), the programmed joints and the commanded
    ones (deg, (n, 6))."""

    t: np.ndarray
    q_ref: np.ndarray
    q_cmd: np.ndarray

    def save(self, path: str | Path) -> None:
        """Every field to the ``.npz`` at ``path``."""
        np.savez(path, **{f.name: getattr(self, f.name) for f in fields(self)})

    @classmethod
    def load(cls, path: str | Path):
        """The log `save` wrote to ``path``; ValueError when a field is missing (another type's file)."""
        with np.load(path) as z:
            missing = [f.name for f in fields(cls) if f.name not in z.files]
            if missing:
                raise ValueError(f"{path}: not a {cls.__name__}: it lacks {', '.join(missing)}")
            return cls(**{f.name: _SCALARS[f.type](z[f.name]) if f.type in _SCALARS else z[f.name]
                          for f in fields(cls)})


@dataclass(frozen=True, eq=False)
class DeviceLog(Track):
    """What a virtual device's log holds whichever device it is: per cycle the correction applied (q_cmd - q_ref,
    deg); the device's cycle (s), the clock time (CLOCK_MONOTONIC, s) of program time 0 (0 in lock step) and
    the cycles it ran late (its deadlines exceeded)."""

    device: ClassVar[str]               # its name in a sentence ("the virtual PLC")
    kind: ClassVar[str]                 # its key in a pass's report

    applied: np.ndarray
    period: float
    t0: float
    overruns: int

    def counts(self) -> dict:
        """The device's counts for a pass's report."""
        return {"cycles": len(self.t), "overruns": self.overruns}


@dataclass(frozen=True, eq=False)
class PlcLog(DeviceLog):
    """The virtual PLC's cycles: per cycle when its requests were done (``t_read``: CLOCK_MONOTONIC, s; lock step:
    the program time), whether its link to the service was alive (the program's ``bAlive``) and the service's
    record as the program read it (``to_plc``: the register map's to_plc values in their order, NaN while the
    link is down); for the run the addresses the program wrote (``written``), the requests that failed
    (``errors``) and what it dialled (``dialled``: "Modbus host:port unit n", "ADS net-id port n")."""

    t_read: np.ndarray
    link: np.ndarray
    to_plc: np.ndarray
    written: np.ndarray
    errors: int
    dialled: np.ndarray

    device: ClassVar[str] = "PLC"
    kind: ClassVar[str] = "plc"

    def counts(self) -> dict:
        return {**super().counts(), "modbus_errors": self.errors}


@dataclass(frozen=True, eq=False)
class RobotLog(DeviceLog):
    """The virtual robot's interpolation cycles: per cycle its deadline (``due``, CLOCK_MONOTONIC, s), whether it
    sent a packet (``sent``), whether the packet's answer came within the cycle (``answered``) and its round trip
    (``rtt_s``, NaN when late or no packet); for the run the answers that came late or not at all (``late``) and
    the program time the robot stopped after too many in a row (``stopped_at``, NaN when it never stopped)."""

    due: np.ndarray
    sent: np.ndarray
    answered: np.ndarray
    rtt_s: np.ndarray
    late: int
    stopped_at: float

    device: ClassVar[str] = "robot"
    kind: ClassVar[str] = "robot"

    def counts(self) -> dict:
        return {**super().counts(), "late_answers": self.late}

    def reply_latency_p99_ms(self) -> float | None:
        """The 99th percentile of the answers' round trip (ms, the answers that came in their cycle); None
        without one."""
        ok = self.rtt_s[np.isfinite(self.rtt_s)]
        return round(1000.0 * float(np.percentile(ok, 99)), 3) if len(ok) else None
