"""Absolute deadlines, the one schedule every periodic loop of stiffcomp runs on.

``due += period`` after every cycle: the work time never accumulates into drift. The one catch-up
rule: a cycle that ends after the next deadline has *exceeded*; the deadlines that passed entirely
during it are skipped and counted as exceeded too (TwinCAT's exceed counter), and the next cycle
starts at once on the latest deadline that has passed. A loaded host therefore never bursts to catch
up, and ``cycles + exceeded`` accounts for every deadline.

The cycle task (`service.task.CyclicTask`), the virtual PLC, the Modbus client role, `stiffcomp
record` and the benchmarks all use `Deadlines`; they differ only in how they wait (`sleep_until`,
`wait_async`). `cancel` stops such a loop when it runs as an asyncio task.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Callable


class Deadlines:
    """The deadlines of one periodic loop.

    Parameters
    ----------
    period_s : float
    start : float
        The first deadline (clock time).
    clock : callable () -> float
    """

    def __init__(self, period_s: float, start: float | None = None, clock: Callable[[], float] = time.monotonic):
        self.period = float(period_s)
        self.clock = clock
        self.due = clock() if start is None else float(start)
        self.exceeded = 0           # deadlines exceeded or skipped

    def advance(self, end: float) -> bool:
        """Move past a cycle that ended at ``end``; True if it exceeded (the count is in ``exceeded``)."""
        self.due += self.period
        if end <= self.due:
            return False
        missed = int((end - self.due) // self.period)
        self.due += missed * self.period
        self.exceeded += 1 + missed
        return True

    def sleep_until(self, spin_s: float = 0.0, sleep: Callable[[float], None] = time.sleep) -> None:
        """Block until the deadline; with ``spin_s``, sleep until that long before it and then poll the clock
        (yielding with sleep(0))."""
        clock, due = self.clock, self.due
        now = clock()
        if due - spin_s > now:
            sleep(due - spin_s - now)
        while clock() < due:
            sleep(0)

    async def wait_async(self) -> None:
        """Await the deadline on an asyncio loop."""
        delay = self.due - self.clock()
        if delay > 0:
            await asyncio.sleep(delay)


CANCEL_AGAIN_S = 0.05


async def cancel(task: asyncio.Task | None) -> None:
    """Cancel a periodic task and wait until it has ended (the I/O parts' one way to stop one).

    A cancel can be lost. Before Python 3.12, ``asyncio.wait_for`` returns the awaited result, and
    drops the cancel, when the result arrives in the same step of the loop as the cancel; pymodbus
    awaits every reply so. The periodic loop then runs on, and a stop waited for it until the I/O
    process was killed. The cancel is therefore sent again every `CANCEL_AGAIN_S` until the task
    has ended. An exception the task ended with is raised here.
    """
    if task is None:
        return
    while not task.done():
        task.cancel()
        await asyncio.wait((task,), timeout=CANCEL_AGAIN_S)
    if not task.cancelled() and task.exception() is not None:
        raise task.exception()
