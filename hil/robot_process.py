"""The virtual robot of a HIL run through the robot road, in its own process: the circle's programmed joints
sent over KUKA RSI or ABB EGM on the robot's clock, the answers applied as the controller would.

It writes the same log as the virtual PLC (`hil.plc_process`): per robot cycle the program time, the
programmed joints ``q_ref``, the commanded ones ``q_cmd`` and the applied correction, so the robot stub and
every figure of `stiffcomp hil circle` read it alike; plus each answer's round trip (``rtt_s``, NaN when late or
no packet that cycle), the late answers and when the robot stopped after too many of them.
"""

from __future__ import annotations

import gc
import logging
import time

import numpy as np

from plc_interface.robot.settings import RobotSettings

from .priority import as_a_robot_controller
from .virtual_robot import VirtualRobot, controller_for, run_cycles
from .world import World

hil_log = logging.getLogger("stiffcomp.hil")


def robot_main(scenario, robot, settings: RobotSettings, port: int, out_file: str, go_value, ready) -> None:
    """Process entry: report ready, wait for the start time in ``go_value``, run the cut, save the log."""
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
        log = run(vr, world.t_start, world.t_end, go_value.value)
        np.savez(out_file, **log, written=np.array([], dtype=int), period=controller.period, t0=go_value.value)
    finally:
        vr.close()


def run(vr: VirtualRobot, t_start: float, t_end: float, t0: float) -> dict:
    """The robot's cycles from program time ``t_start`` to ``t_end`` (t = clock - ``t0``), logged as the virtual
    PLC logs its own (`CycleLog`'s arrays), with each answer's round trip beside.
    (In the uncompensated pass the service is not enabled, so its answers carry no correction.)"""
    cy = run_cycles(vr, t_start, t_end, t0)
    a = cy.arrays()
    return {"t": a["t"], "t_read": a["due"], "link": a["answered"] | ~a["sent"], "q_ref": a["q_ref"],
            "q_cmd": a["q_cmd"], "applied": a["applied"], "to_plc": np.full((cy.k, 0), np.nan),
            "rtt_s": a["rtt_s"], "sent": a["sent"], "late": vr.c.late, "overruns": cy.overruns,
            "stopped_at": np.nan if vr.stopped_at is None else vr.stopped_at}
