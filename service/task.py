"""The cyclic task: absolute deadlines, TwinCAT-style task info, the statistics of a run, and stop.

The loop runs on `io_base.deadlines.Deadlines` (the project's one schedule and its one catch-up
rule: a cycle that ends after the next deadline has exceeded, and the deadlines it skipped count as
exceeded too). The work function receives the time (s since start) and whether the previous cycle
exceeded.

Nothing in the cycle waits for memory or the collector: the cycle thread locks the process's pages
(``mlockall``, where permitted, one warning where not, as for SCHED_FIFO), and once the start-up's
objects are frozen (`gc.freeze`) the collector is off (`gc.disable`); a young-generation collection runs
only after a cycle's work, when the young objects have piled up and more than half the period is left
(or they have piled up ten times over: memory must not grow without bound on an overloaded host).

Stop is a request the cycle handles: `CyclicTask.request_stop` sets a flag the work function reads
(``stop_requested``). A work function that handles stop itself (the service ramps the correction to
zero in its own cycles) returns True while it goes on and False when it is done; a plain work function
returns None and the task ends at the first cycle after the request. Nothing polls the cycle from
another thread.
"""

from __future__ import annotations

import ctypes
import errno
import gc
import logging
import os
import threading
import time
from collections.abc import Callable

import numpy as np
from pydantic import Field

from io_base.deadlines import Deadlines
from io_base.scheduling import hold_cpu_latency, set_fifo
from stiffness.files.yaml_schema import Strict

log = logging.getLogger("stiffcomp.task")

MCL_CURRENT, MCL_FUTURE, MCL_ONFAULT = 1, 2, 4       # <sys/mman.h>
GC_YOUNG = 20_000        # young objects that make the collection after a cycle's work worth its time
GC_SLACK = 0.5           # ... when more than this share of the period is left before the next deadline
GC_YOUNG_MAX = 200_000   # ... or at once beyond this: an overloaded host must not grow the memory without bound


def unlock_memory() -> None:
    """munlockall: undo `lock_memory` (a task that ends in a process that goes on, e.g. a test's)."""
    try:
        ctypes.CDLL(None).munlockall()
    except (OSError, AttributeError):
        pass


def lock_memory() -> str | None:
    """mlockall: the pages in use now and later stay in RAM (faulted in as they are touched, so the lock
    costs milliseconds, not a pass over the whole process). None, or why it was not permitted."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        if libc.mlockall(MCL_CURRENT | MCL_FUTURE | MCL_ONFAULT) == 0:
            return None
        err = ctypes.get_errno()
        if err == errno.EINVAL and libc.mlockall(MCL_CURRENT | MCL_FUTURE) == 0:     # a kernel before 4.4
            return None
        return os.strerror(ctypes.get_errno() or err)
    except (OSError, AttributeError) as e:
        return str(e)


class CycleConfig(Strict):
    """``cycle``: the period, the statistics, and how the task is scheduled (priority, CPU, spin)."""

    period_ms: float = Field(1.0, ge=0.1, le=100.0)
    stats_log_interval_s: float = Field(10.0, ge=0.0)
    history: int = Field(600_000, ge=1000, le=10_000_000)
    realtime_priority: int = Field(0, ge=0, le=99)
    cpu: int | None = Field(None, ge=0, le=1023)
    spin_us: float = Field(0.0, ge=0.0, le=1000.0)
    compiled: bool = True
    lock_memory: bool = True
    cpu_latency_us: int | None = Field(None, ge=0, le=1_000_000)


class TaskInfo:
    """What TwinCAT shows for a task: cycle time, count, last exec time, exceed counter, jitter.

    Per-cycle exec times and period jitters are kept in ring buffers of ``history`` cycles.
    """

    def __init__(self, period_s: float, history: int = 600_000):
        self.period_s = period_s
        self.cycle_count = 0
        self.exceed_count = 0
        self.last_exec_s = 0.0
        self.last_jitter_s = 0.0
        self.last_exceeded = False
        self.max_exec_s = 0.0
        self.max_jitter_s = 0.0
        self._exec = np.zeros(history)
        self._jitter = np.zeros(history)
        self._n_jitter = 0

    def record(self, exec_s: float, jitter_s: float | None) -> None:
        k = self.cycle_count % len(self._exec)
        self._exec[k] = exec_s
        self.last_exec_s = exec_s
        self.max_exec_s = max(self.max_exec_s, exec_s)
        if jitter_s is not None:
            self._jitter[self._n_jitter % len(self._jitter)] = jitter_s
            self._n_jitter += 1
            self.last_jitter_s = jitter_s
            self.max_jitter_s = max(self.max_jitter_s, jitter_s)
        self.cycle_count += 1

    def stats(self) -> dict:
        """The ``--stats-json`` document (µs)."""
        ex = self._exec[: min(self.cycle_count, len(self._exec))] * 1e6
        ji = self._jitter[: min(self._n_jitter, len(self._jitter))] * 1e6

        def pct(a: np.ndarray, p: float) -> float:
            return round(float(np.percentile(a, p)), 2) if len(a) else 0.0

        return {"cycles": self.cycle_count, "exceed_count": self.exceed_count,
                "exec_us": {"p50": pct(ex, 50), "p99": pct(ex, 99), "max": round(self.max_exec_s * 1e6, 2)},
                "period_jitter_us": {"p99": pct(ji, 99), "p999": pct(ji, 99.9),
                                     "max": round(self.max_jitter_s * 1e6, 2)}}


class CyclicTask:
    """Run ``work(t, exceeded) -> bool`` every ``period_s`` in its own thread, on absolute deadlines.

    Parameters
    ----------
    period_s : float
    work : callable (t: float, exceeded: bool) -> bool or None
        t is the cycle's start time in s since the task started; False ends the task, True goes on even
        after a stop request, None goes on until a stop request.
    info : TaskInfo
    on_error : callable (BaseException) -> None
        The policy for an exception escaping ``work``: the task stops after calling it.
    realtime_priority : int
        SCHED_FIFO priority to request (0 = leave the scheduler alone).
    cpu : int or None
        Pin the cycle thread to this CPU.
    spin_s : float
        Sleep until ``spin_s`` before the deadline, then poll the clock (yielding with sleep(0)). On
        virtual machines a core that never idles wakes with warm caches, at the price of that fraction
        of a core.
    lock_memory : bool
        mlockall before the first cycle (`lock_memory`; one warning where not permitted).
    cpu_latency_us : int or None
        While the task runs, hold the CPUs' idle wake-up latency within this many µs
        (`io_base.scheduling.hold_cpu_latency`; one warning where not permitted); None: the kernel's.
    prepare : callable () -> None, optional
        Called ``lead_s`` before each deadline, between two cycles (the sensor's request: its answer is
        then read by the cycle at that deadline); right away when the last cycle ended later than that.
    """

    def __init__(self, period_s: float, work: Callable[[float, bool], bool | None], info: TaskInfo,
                 on_error: Callable[[BaseException], None], realtime_priority: int = 0,
                 clock: Callable[[], float] = time.perf_counter, cpu: int | None = None, spin_s: float = 0.0,
                 lock_memory: bool = False, prepare: Callable[[], None] | None = None, lead_s: float = 0.0,
                 cpu_latency_us: int | None = None):
        self.period = float(period_s)
        self.work = work
        self.info = info
        self.on_error = on_error
        self.priority = realtime_priority
        self.cpu = cpu
        self.spin = float(spin_s)
        self.lock = lock_memory
        self._locked = False
        self.cpu_latency_us = cpu_latency_us
        self._latency_fd: int | None = None
        self.prepare = prepare if lead_s > 0 else None
        self.lead = float(lead_s)
        self.clock = clock
        self.stop_requested = False
        self.stopped = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stiffcomp-cycle", daemon=True)
        self.error: BaseException | None = None

    def start(self) -> None:
        self._thread.start()

    def request_stop(self) -> None:
        """Ask the cycle to finish (it reads ``stop_requested``); returns at once."""
        self.stop_requested = True

    def stop(self, timeout: float = 5.0) -> bool:
        """Request the stop and wait for the task to end; True if it did."""
        self.request_stop()
        return self.join(timeout)

    def join(self, timeout: float | None = None) -> bool:
        """Wait for the task to end; True if it did."""
        self._thread.join(timeout)
        return not self._thread.is_alive()

    @property
    def running(self) -> bool:
        return self._thread.is_alive()

    def _set_priority(self) -> None:
        if self.lock:
            why = lock_memory()
            self._locked = why is None
            if why:
                log.warning("cannot lock the service's memory (mlockall: %s); pages may be swapped out under "
                            "memory pressure (CAP_IPC_LOCK or a higher RLIMIT_MEMLOCK permits it)", why)
        if self.cpu_latency_us is not None:
            self._latency_fd, why = hold_cpu_latency(self.cpu_latency_us)
            if why:
                log.warning("cannot hold the CPUs' idle wake-up within %d us (%s); an idle CPU may wake late for a "
                            "deadline or a packet (root, or write access to the device by a udev rule, permits it)",
                            self.cpu_latency_us, why)
        if self.cpu is not None:
            try:
                os.sched_setaffinity(0, {self.cpu})
            except (OSError, AttributeError) as e:
                log.warning("cannot pin the cycle thread to CPU %d (%s)", self.cpu, e)
        set_fifo(self.priority, "cycle thread", log)

    def _run(self) -> None:
        self._set_priority()
        gc.collect()
        gc.freeze()              # objects made at start-up never get scanned again
        was_enabled = gc.isenabled()
        gc.disable()             # no collection at an allocation in the cycle: only after the work (below)
        clock, info, work, spin = self.clock, self.info, self.work, self.spin
        period, collect, count = self.period, gc.collect, gc.get_count
        prepare, lead, sleep = self.prepare, self.lead, time.sleep
        deadlines = Deadlines(self.period, clock=clock)
        t0 = deadlines.due
        prev_start: float | None = None
        exceeded = False
        try:
            go_on: bool | None = None
            while go_on is True or (go_on is None and not self.stop_requested):
                if prepare is not None:
                    ahead = deadlines.due - lead - clock()
                    if ahead > 0:
                        sleep(ahead)
                    prepare()
                deadlines.sleep_until(spin)
                start = clock()
                go_on = work(start - t0, exceeded)
                end = clock()
                info.record(end - start, None if prev_start is None else abs(start - prev_start - self.period))
                prev_start = start
                exceeded = info.last_exceeded = deadlines.advance(end)
                info.exceed_count = deadlines.exceeded
                young = count()[0]
                if young > GC_YOUNG and (deadlines.due - clock() > GC_SLACK * period or young > GC_YOUNG_MAX):
                    collect(0)
        except BaseException as e:  # noqa: BLE001 - handed to the explicit policy below
            self.error = e
            self.on_error(e)
        finally:
            if self._locked:
                unlock_memory()
            if self._latency_fd is not None:
                os.close(self._latency_fd)
            if was_enabled:
                gc.enable()
            gc.unfreeze()
            self.stopped.set()
