"""The virtual robot of a HIL run through the robot road, in its own process: the circle's programmed joints
sent over KUKA RSI or ABB EGM on the robot's clock, the answers applied as the controller would.

It writes the same log as the virtual PLC (`hil.plc_process`): per robot cycle the program time, the
programmed joints ``q_ref``, the commanded ones ``q_cmd = q_ref + applied`` and the applied correction, so
the robot stub and every figure of `stiffcomp hil circle` read it alike; plus each answer's round trip
(``rtt_s``, NaN when late), the late answers and when the robot stopped after too many of them.
"""

from __future__ import annotations

import gc
import time

import numpy as np

from plc_interface.deadlines import Deadlines
from plc_interface.robot.settings import RobotSettings

from .priority import below_the_service
from .virtual_plc import CycleLog
from .virtual_robot import RobotController, VirtualRobot
from .world import World

TIMEOUT_COUNT = 100         # late answers in a row before the robot stops (RSI's ETHERNET default)


def robot_main(scenario, robot, settings: RobotSettings, port: int, out_file: str, go_value, ready) -> None:
    """Process entry: report ready, wait for the start time in ``go_value``, run the cut, save the log."""
    below_the_service()
    world = World(scenario, robot)
    controller = RobotController(settings, robot)
    vr = VirtualRobot(controller, "127.0.0.1", port, world.path.q_ref_deg, TIMEOUT_COUNT)
    try:
        gc.collect()
        gc.freeze()         # a controller's loop: no long collection of the imports while it runs
        ready.set()
        while go_value.value <= 0:
            time.sleep(0.005)
        log = run(vr, world.t_start, world.t_end, go_value.value)
        np.savez(out_file, **log, written=np.array([], dtype=int), period=controller.period, t0=go_value.value)
    finally:
        vr.close()


def run(vr: VirtualRobot, t_start: float, t_end: float, t0: float) -> dict:
    """The robot's cycles from program time ``t_start`` to ``t_end`` (t = clock - ``t0``) on absolute deadlines,
    logged as the virtual PLC logs its own (`CycleLog`), with each answer's round trip beside.
    (In the uncompensated pass the service is not enabled, so its answers carry no correction.)"""
    c = vr.c
    n = int((t_end - t_start) / c.period) + 16
    lg, rtt = CycleLog(n, 0), np.full(n, np.nan)
    deadlines = Deadlines(c.period, start=t0 + t_start)
    while deadlines.due - t0 <= t_end and lg.k < n:
        deadlines.sleep_until()
        k, tk = lg.k, deadlines.due - t0
        if vr.stopped_at is None:
            lg.link[k], rtt[k] = vr.cycle(tk, deadlines.due + c.period)
        lg.t[k], lg.t_read[k], lg.q_ref[k], lg.applied[k] = tk, deadlines.due, vr.reference(tk), c.applied
        # a stopped robot holds where it stood
        lg.q_cmd[k] = lg.q_ref[k] + lg.applied[k] if vr.stopped_at is None or k == 0 else lg.q_cmd[k - 1]
        lg.k += 1
        deadlines.advance(time.monotonic())
    return {**lg.arrays(), "rtt_s": rtt[:lg.k], "late": c.late, "overruns": deadlines.exceeded, "errors": c.late,
            "stopped_at": np.nan if vr.stopped_at is None else vr.stopped_at}
