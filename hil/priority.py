"""The virtual devices run below the service they test.

The virtual sensor, PLC and robot stub stand for separate hardware: on a real cell they have their own
processors and never take the service's. On one machine they share its cores, so each device process
lowers its own priority to nice ``DEVICE_NICE`` (5) at its start: when a core is contended, the service (at
its documented priority: SCHED_FIFO where permitted, else nice 0) runs first, and the devices take the
time that is left, which is plenty for their light work (a CAN answer per request, a Modbus exchange per
PLC cycle). `benchmarks/bench_hil_deadlines.py` measures the circle's exceeded share with and without.
"""

from __future__ import annotations

import os

DEVICE_NICE = 5


def below_the_service() -> None:
    """Lower this process to nice ``DEVICE_NICE`` (a process may always lower its own priority)."""
    try:
        now = os.nice(0)
        if now < DEVICE_NICE:
            os.nice(DEVICE_NICE - now)
    except OSError:
        pass
