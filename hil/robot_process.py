"""The virtual robot of a HIL run through the robot road, in its own process: the circle's programmed joints
sent over KUKA RSI or ABB EGM on the robot's clock, the answers applied as the controller would.

It writes the robot's log (`hil.device_log.RobotLog`): per robot cycle the program time, the programmed joints
``q_ref``, the commanded ones ``q_cmd`` and the applied correction, the track the robot stub and every figure of
`stiffcomp hil circle` read as they read the PLC's; and the robot's own: each cycle's deadline, its packet and
its answer's round trip (``rtt_s``, NaN when late or no packet that cycle), the late answers and when the robot
stopped after too many of them.
"""

from __future__ import annotations

import gc
import logging
import time

import numpy as np

from robot_road.settings import RobotSettings

from .device_log import RobotLog
from .priority import as_a_robot_controller
from .virtual_robot import VirtualRobot, controller_for, run_cycles
from .world import World

hil_log = logging.getLogger("stiffcomp.hil")


def robot_main(scenario, robot, settings: RobotSettings, port: int, out_file: str, go_value, ready) -> None:
    """Process entry: report ready, wait for the start time in ``go_value``, run the cut, save its log to
    ``out_file``."""
    as_a_robot_controller(hil_log)
    world = World(scenario, robot)
    controller = controller_for(settings, robot, delay_s=scenario.plc.extra_delay_ms / 1000.0)
    vr = VirtualRobot(controller, "127.0.0.1", port, world.path.q_ref_deg)
    try:
        gc.collect()
        gc.freeze()         # a controller's loop: no long collection of the imports while it runs
        ready.set()
        while go_value.value <= 0:
            time.sleep(0.005)
        run(vr, world.t_start, world.t_end, go_value.value).save(out_file)
    finally:
        vr.close()


def run(vr: VirtualRobot, t_start: float, t_end: float, t0: float) -> RobotLog:
    """The robot's cycles from program time ``t_start`` to ``t_end`` (t = clock - ``t0``) as the robot's log.
    (In the uncompensated pass the service is not enabled, so its answers carry no correction.)"""
    cy = run_cycles(vr, t_start, t_end, t0)
    return RobotLog(t=cy.t, q_ref=cy.q_ref, q_cmd=cy.q_cmd, applied=cy.applied, period=vr.controller.period, t0=t0,
                    overruns=cy.overruns, due=cy.due, sent=cy.sent, answered=cy.answered, rtt_s=cy.rtt_s,
                    late=vr.controller.late, stopped_at=np.nan if vr.stopped_at is None else vr.stopped_at)
