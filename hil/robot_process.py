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
    """The robot's cycles from program time ``t_start`` to ``t_end`` (t = clock - ``t0``) on absolute deadlines.
    (In the uncompensated pass the service is not enabled, so its answers carry no correction.)"""
    c = vr.c
    n = int((t_end - t_start) / c.period) + 16
    t, q_ref, q_cmd, applied, rtt = (np.full(n, np.nan), np.zeros((n, 6)), np.zeros((n, 6)), np.zeros((n, 6)),
                                     np.full(n, np.nan))
    link = np.zeros(n, dtype=bool)
    deadlines = Deadlines(c.period, start=t0 + t_start)
    k = 0
    while deadlines.due - t0 <= t_end and k < n:
        deadlines.sleep_until()
        tk = deadlines.due - t0
        if vr.stopped_at is None:
            link[k], rtt[k] = vr.cycle(tk, deadlines.due + c.period)
        t[k], q_ref[k], applied[k] = tk, vr.reference(tk), c.applied
        # a stopped robot holds where it stood
        q_cmd[k] = q_ref[k] + applied[k] if vr.stopped_at is None or k == 0 else q_cmd[k - 1]
        k += 1
        deadlines.advance(time.monotonic())
    return {"t": t[:k], "t_read": t[:k] + t0, "link": link[:k], "q_ref": q_ref[:k], "q_cmd": q_cmd[:k],
            "applied": applied[:k], "to_plc": np.full((k, 0), np.nan), "rtt_s": rtt[:k], "late": c.late,
            "overruns": deadlines.exceeded, "errors": c.late,
            "stopped_at": np.nan if vr.stopped_at is None else vr.stopped_at}
