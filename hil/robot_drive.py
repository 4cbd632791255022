"""A virtual robot driven for a while on its own clock, each packet and answer recorded (tests, benchmarks)."""

from __future__ import annotations

import gc
import logging
import os
import time
from dataclasses import dataclass

import numpy as np
from scipy import stats

from io_base.scheduling import set_fifo

from .virtual_robot import VirtualRobot, run_cycles

log = logging.getLogger("stiffcomp.hil")


@dataclass
class Drive:
    """Per packet: when it left (unix s), its stamp, the programmed and commanded joints of its cycle, whether
    its answer came in its cycle, the answer's values (NaN when none), the round trip (s; NaN when late), for an
    EGM path correction the path frame the robot read it in, and how long after its deadline it left."""

    sent_unix: np.ndarray
    stamp: np.ndarray
    q_ref: np.ndarray
    q_cmd: np.ndarray
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

    def late_beyond(self, rate: float, significance: float = 0.01, lag_s: float = 0.001) -> bool:
        """Whether the late answers to packets sent on time (`late_on_time`) show, by a one-sided binomial test
        at ``significance``, that more than ``rate`` of the answers come late. A count compared with ``rate`` x
        the packets instead would fail a road that keeps ``rate`` exactly in 28 % of 10 s EGM path runs (209
        packets: 2 late or more), where a host that stalls a process for a few ms now and then is enough."""
        return bool(stats.binom.sf(self.late_on_time(lag_s) - 1, len(self.answered), rate) < significance)

    def silences(self, longer_than_s: float) -> int:
        """How often the robot sent nothing for longer than ``longer_than_s`` between two packets (its own host
        stalled): after each, the road rightly begins a new session (`faults.plc_heartbeat_timeout_ms`)."""
        return int((np.diff(self.sent_unix) > longer_than_s).sum())

    def packets_before(self, unix_s: float, span_s: float, slack_s: float = 0.005) -> np.ndarray:
        """The packets that can have reached the service by ``unix_s`` (sent up to ``slack_s`` after it: the robot's
        and the service's stamps are two clocks), the newest covering ``span_s`` of the robot's cycles, counted in
        packets, not in time: after the host stalls the row of ``unix_s`` can still hold a packet sent before the
        stall, which a window of time would have left out."""
        period = float(np.median(np.diff(self.sent_unix)))
        return newest_up_to(self.sent_unix, unix_s + slack_s, int(np.ceil(span_s / period)))


def newest_up_to(stamps: np.ndarray, until: float, count: int) -> np.ndarray:
    """The indices of the newest ``count`` of the rising ``stamps`` at or before ``until``: a window counted in
    rows, which a host's stall does not empty as a window of time would."""
    end = int(np.searchsorted(stamps, until, side="right"))
    return np.arange(max(0, end - count), end)


def drive(vr: VirtualRobot, seconds: float, t0: float | None = None, priority: int = 0) -> Drive:
    """Run ``vr`` for ``seconds`` of its cycles (program time from ``t0``, clock time, default now): each packet
    sent on its deadline, its answer awaited until the next cycle. ``priority``: SCHED_FIFO for this thread while
    it drives (a robot controller is a real-time machine of its own; where the host does not permit it, normal
    scheduling, with one warning)."""
    fifo = set_fifo(priority, "virtual robot", log)
    try:
        now = time.monotonic()
        t0 = now if t0 is None else t0
        gc.collect()
        gc.freeze()             # a controller's loop: no long collection of what was there before it began
        start = now - t0
        cy = run_cycles(vr, start, start + seconds - vr.controller.period, t0)
    finally:
        if fifo:
            os.sched_setscheduler(0, os.SCHED_OTHER, os.sched_param(0))
    k = cy.sent
    return Drive(cy.sent_unix[k], cy.stamp[k], cy.q_ref[k], cy.q_cmd[k], cy.answered[k], cy.answer[k], cy.rtt_s[k],
                 cy.frames[k], cy.send_lag_s[k])
