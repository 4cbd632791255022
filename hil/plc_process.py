"""The virtual PLC of a HIL run, in its own process: the PLC program on `VirtualPlc`, a Modbus TCP and ADS client
of the service (`hil.cell_network.TcpNetwork`)."""

from __future__ import annotations

import logging
import time

from plc_link.register_map import RegisterMap

from .accelerometer import VirtualAccelerometer
from .cell_network import PlcFaults, TcpNetwork
from .plc_program import PlcProgram
from .priority import as_a_plc, below_the_service
from .virtual_plc import VirtualPlc
from .world import World


def plc_main(scenario, robot, rmap: RegisterMap, port: int, compensate: bool, out_file: str, go_value, ready,
             program_folder: str, faults: PlcFaults | None = None, connect_timeout_s: float = 60.0,
             ads_port: int | None = None, motion=None) -> None:
    """Process entry: load the program, connect, report ready, wait for the start time in ``go_value``, run,
    save its log (`hil.device_log.PlcLog`) to ``out_file``. ``rmap`` is the service config's register map
    (`ServiceConfig.register_map`); ``ads_port`` the service's ADS server (None: not served). Loads and connects
    below the service's priority, then runs its cycle as a PLC (`hil.priority`). ``motion``: the stub's motion
    along the reference (`hil.accelerometer.reference_motion`) for the accelerometer at its tool, None: none."""
    below_the_service()
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)    # refused connections are counted, not printed
    world = World(scenario, robot)
    c = scenario.plc
    network = TcpNetwork("127.0.0.1", port, rmap, faults, c.extra_delay_ms, ads_port=ads_port)
    box = None if motion is None else VirtualAccelerometer(scenario.accelerometer, robot, *motion, world.path.q_ref_deg,
                                                           scenario.payload.g_mps2, c.period_ms / 1000.0)
    plc = VirtualPlc(PlcProgram(program_folder), network, rmap, world.path.q_ref_deg, compensate,
                     c.period_ms / 1000.0, world.plan,
                     {"service_timeout_ms": c.service_timeout_ms, "max_rate_deg_s": c.max_rate_deg_s}, box)
    try:
        if not network.connect(time.monotonic() + connect_timeout_s):
            raise ConnectionError(f"the virtual PLC cannot reach the service at 127.0.0.1:{port}")
        ready.set()
        while go_value.value <= 0:
            time.sleep(0.005)
        as_a_plc(logging.getLogger("hil.plc"))
        plc.run(world.t_start, world.t_end, go_value.value).save(out_file)
    finally:
        network.close()
