"""The virtual PLC of a HIL run, in its own process: the circle program on `VirtualPlc`."""

from __future__ import annotations

import logging
import time

import numpy as np

from hil.virtual_plc import PlcFaults, PlcLogic, VirtualPlc
from plc_interface.register_map import RegisterMap

from .priority import below_the_service
from .world import World


def plc_main(scenario, robot, rmap: RegisterMap, port: int, compensate: bool, out_file: str, go_value, ready,
             faults: PlcFaults | None = None, connect_timeout_s: float = 60.0) -> None:
    """Process entry: connect, report ready, wait for the start time in ``go_value``, run, save the log.
    ``rmap`` is the service config's register map (`ServiceConfig.register_map`). Runs below the
    service's priority (`hil.priority`)."""
    below_the_service()
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)    # refused connections are counted, not printed
    world = World(scenario, robot)
    c = scenario.plc
    logic = PlcLogic(rmap, world.path.q_ref_deg, compensate, c.service_timeout_ms / 1000.0, c.max_rate_deg_s,
                     faults, c.extra_delay_ms / 1000.0, world.plan)
    plc = VirtualPlc(logic, rmap, "127.0.0.1", port, c.period_ms / 1000.0)
    try:
        if not plc.connect(time.monotonic() + connect_timeout_s):
            raise ConnectionError(f"the virtual PLC cannot reach the service at 127.0.0.1:{port}")
        ready.set()
        while go_value.value <= 0:
            time.sleep(0.005)
        log = plc.run(world.t_start, world.t_end, go_value.value)
        np.savez(out_file, **log.arrays(), written=np.array(sorted(plc.written)), overruns=plc.overruns,
                 errors=plc.errors, period=plc.period, t0=go_value.value)
    finally:
        plc.close()
