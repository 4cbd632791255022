"""A virtual robot driven for a while on its own clock, each packet and answer recorded (tests, benchmarks)."""

from __future__ import annotations

import gc
import logging
import os
import time
from dataclasses import dataclass

import numpy as np

from plc_interface.deadlines import Deadlines
from plc_interface.scheduling import set_fifo

from .virtual_robot import VirtualRobot

log = logging.getLogger("stiffcomp.hil")


@dataclass
class Drive:
    """Per robot cycle: when the packet left (unix s), its stamp, the programmed joints, whether its answer came
    in its cycle, the answer's values (NaN when none), the round trip (s; NaN when late) and, for an EGM path
    correction, the path frame the robot read it in."""

    sent_unix: np.ndarray
    stamp: np.ndarray
    q_ref: np.ndarray
    answered: np.ndarray
    answer: np.ndarray
    rtt_s: np.ndarray
    frames: np.ndarray
    send_lag_s: np.ndarray          # how long after its deadline each packet left (the robot's own lateness)

    @property
    def late(self) -> int:
        return int((~self.answered).sum())

    def late_on_time(self, lag_s: float = 0.001) -> int:
        """Late answers to packets the robot sent within ``lag_s`` of their deadline: the ones the robot's own
        lateness (a loaded or stalled host under the virtual robot) does not explain."""
        return int((~self.answered & (self.send_lag_s <= lag_s)).sum())


def drive(vr: VirtualRobot, seconds: float, t0: float | None = None, priority: int = 0) -> Drive:
    """Run ``vr`` for ``seconds`` of its cycles (program time from ``t0``, clock time, default now): each packet
    sent on its deadline, its answer awaited until the next one. ``priority``: SCHED_FIFO for this thread while
    it drives (a robot controller is a real-time machine of its own; where the host does not permit it, normal
    scheduling, with one warning)."""
    fifo = set_fifo(priority, "virtual robot", log)
    try:
        return _drive(vr, seconds, t0)
    finally:
        if fifo:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))


def _drive(vr: VirtualRobot, seconds: float, t0: float | None) -> Drive:
    c = vr.c
    n = max(int(seconds / c.period), 1)
    sent, stamp, rtt = np.zeros(n), np.zeros(n, dtype=np.int64), np.full(n, np.nan)
    q_ref, answered = np.zeros((n, 6)), np.zeros(n, dtype=bool)
    answer, frames, lag = np.full((n, 6), np.nan), np.full((n, 3, 3), np.nan), np.zeros(n)
    t0 = time.monotonic() if t0 is None else t0
    gc.collect()
    gc.freeze()             # a controller's loop: no long collection of what was there before it began
    deadlines = Deadlines(c.period, start=time.monotonic())
    for k in range(n):
        deadlines.sleep_until()
        t = deadlines.due - t0
        lag[k] = time.monotonic() - deadlines.due
        sent[k], q_ref[k] = time.time(), vr.reference(t)
        answered[k], rtt[k] = vr.cycle(t, deadlines.due + c.period)
        stamp[k] = c.stamp
        if answered[k]:
            answer[k, :len(c.answer)] = c.answer
            if c.frame is not None:
                frames[k] = c.frame
        deadlines.advance(time.monotonic())
    return Drive(sent, stamp, q_ref, answered, answer, rtt, frames, lag)
