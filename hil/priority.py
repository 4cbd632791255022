"""The virtual devices run below the service they test.

The virtual sensor, PLC and robot stub stand for separate hardware: on a real cell they have their own
processors and never take the service's. On one machine they share its cores, so each device process
lowers its own priority to nice ``DEVICE_NICE`` (5) at its start: when a core is contended, the service (at
its documented priority: SCHED_FIFO where permitted, else nice 0) runs first, and the devices take the
time that is left, which is plenty for their light work (a CAN answer per request, a Modbus exchange per
PLC cycle). `benchmarks/bench_hil_deadlines.py` measures the circle's exceeded share with and without.

The controllers are the exception, as a cell has them: a robot controller and a PLC are real-time machines of
their own. The virtual robot's loop runs at SCHED_FIFO ``ROBOT_FIFO`` and the service's I/O process that answers
it at ``robot.realtime_priority`` ``ROAD_IO_FIFO`` (docs/robot.md); the virtual PLC's cycle, once its program is
loaded and its connections made, at ``PLC_FIFO``: all below the cycle's 50, where the host permits it (else as
the other devices). On a host whose cores are busy with other work, a robot at nice 5 sent late and took its
answers late: through EGM's 48 ms path corrections 74 late answers in one cut, and a part that `part learn`
refused as not fitting the model. The PLC, which runs its TwinCAT program through the ST runtime and a Modbus or
ADS client (about 0.6 ms of work every 2 ms), ran 754 and 1075 of the 2409 cycles a cut owes it at nice 5
beside two busy processes, and the end-to-end delay could not be told from so few.
"""

from __future__ import annotations

import os

DEVICE_NICE = 5
ROBOT_FIFO, ROAD_IO_FIFO = 45, 40       # the virtual robot's loop, the service's I/O process on the robot road
PLC_FIFO = 45                           # the virtual PLC's cycle (a cell has a PLC or a robot road, not both)


def below_the_service() -> None:
    """Lower this process to nice ``DEVICE_NICE`` (a process may always lower its own priority)."""
    try:
        now = os.nice(0)
        if now < DEVICE_NICE:
            os.nice(DEVICE_NICE - now)
    except OSError:
        pass


def as_a_robot_controller(log) -> None:
    """The virtual robot's process: SCHED_FIFO ``ROBOT_FIFO`` where permitted (one line in ``log``), else
    below the service as the other devices."""
    from io_base.scheduling import set_fifo

    if not set_fifo(ROBOT_FIFO, "virtual robot", log):
        below_the_service()


def as_a_plc(log) -> None:
    """The virtual PLC's cycle: SCHED_FIFO ``PLC_FIFO`` where permitted (one line in ``log``), else below the
    service as the other devices (the process starts there: `below_the_service`)."""
    from io_base.scheduling import set_fifo

    set_fifo(PLC_FIFO, "virtual PLC", log)
