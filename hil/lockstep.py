"""The HIL in lock step: the service, the virtual sensor and the virtual PLC stepped together in one process,
as fast as the host runs them (`stiffcomp hil circle --lockstep`).

The same parts as the real-time run (`hil.run`), without the protocols' transport and without real time:

* the service is `service.app.Service` itself, its `work` called once per 1 ms step: its process image, its
  contract record and its trace ring (`--trace`) are the real ones; no I/O process and no task thread;
* the sensor is the HIL's `HilSensor`: its frames (the ATI protocol, noise, its own low-pass and clock) go
  to the service's source decoder one cycle after the request, as ``request_each_cycle`` has them;
* the PLC is the TwinCAT program the cell loads (`hil.virtual_plc.VirtualPlc`) on its own period, its Modbus
  requests served by the image in the same process (`hil.cell_network.ImageNetwork`: the image's Modbus rules
  apply), each taken at the program's next cycle as in real time;
* the robot stub evaluates the pass as in real time (`hil.report.evaluate`).

So a pass takes a second or two instead of its real length plus three process start-ups, and gives the
same figures on a busy host as on a quiet one: what tests and what-ifs need. What it leaves out is what
real time adds: late cycles, Modbus latency, a stalled process (the real-time run shows those).
"""

from __future__ import annotations

import random
from pathlib import Path

import can
import numpy as np

from service.app import Service
from service.config import load_config
from service.run_stats import dynamics_stats
from service.sources.base import FtSource
from service.trace import TraceOptions
from stiffness.data.trace_file import TraceFile
from stiffness.model.stiffness_model import StiffnessModel

from .accelerometer import VirtualAccelerometer, reference_motion
from .cell_network import ImageNetwork
from .device_log import PlcLog
from .run import PassResult, pass_program, write_service_config
from .scenario import Scenario
from .sensor import HilSensor
from .virtual_plc import VirtualPlc
from .world import World

WARM_UP_S = 1.0          # the service runs this long before the PLC's program starts (as it starts first)


class FramesSource(FtSource):
    """The service's F/T source fed by a sensor's answers in process, timed as the CAN source times them:
    with a lead (``source.can.request_lead_us``) the request goes ``lead_s`` before the cycle and the cycle
    reads its answer; without one, each poll returns the answer to the previous cycle's request."""

    def __init__(self, sensor: HilSensor, lead_s: float = 0.0, **common):
        super().__init__(**common)
        self.sensor = sensor
        self.lead_s = float(lead_s)
        self.pending: list[tuple[int, bytes]] = []
        self.scenario_t = 0.0           # the scenario time of the cycle that polls next (set by the loop)

    def request(self) -> None:
        self.pending = self.sensor.answer_at(self.scenario_t - self.lead_s)

    @classmethod
    def from_config(cls, section, timeout_s, resolve):
        raise NotImplementedError("the lock-step HIL builds its source from its sensor, not from a config")

    def _frames(self, t: float):
        out, self.pending = self.pending, ([] if self.lead_s else self.sensor.answer_at(self.scenario_t))
        return [(arb, data, False) for arb, data in out]


def run_lockstep(scenario: Scenario, truth: StiffnessModel, model_path: Path, compensate: bool, folder: Path,
                 service_overrides: dict | None = None, trace: Path | None = None,
                 plc_program: Path | None = None) -> PassResult:
    """One pass in lock step; returns what `hil.run.run_pass` returns (the PLC's log, the service's stats).
    ``plc_program``: the TwinCAT program's folder (by default the library generated for the pass's config)."""
    folder.mkdir(parents=True, exist_ok=True)
    cfg_path = write_service_config(scenario, model_path, folder, f"239.74.{random.randint(1, 254)}.1", 1, 1,
                                     service_overrides)
    cfg = load_config(cfg_path)
    world = World(scenario, truth.robot, scenario.payload, truth.input_map())
    bus = can.Bus(interface="virtual", channel=f"lockstep-{id(world)}")
    sensor = HilSensor(bus, _protocol(cfg), world,
                       lambda: None, [scenario.sensor.noise_N] * 3 + [scenario.sensor.noise_Nm] * 3,
                       scenario.sensor.seed, None, scenario.sensor.rate_hz, scenario.sensor.lowpass_hz)
    bus_cfg = cfg.source.can
    lead = bus_cfg.request_lead_us * 1e-6 if bus_cfg.request_each_cycle else 0.0
    source = FramesSource(sensor, lead, **FtSource.common_args(cfg.source, cfg.faults.sensor_timeout_ms / 1000.0))
    service = Service(cfg, TraceOptions(Path(trace)) if trace is not None else None, source=source)
    service.wait_compiled()
    out_file = TraceFile(trace) if trace is not None else None
    program = pass_program(cfg, plc_program, folder)
    try:
        box = None
        if scenario.accelerometer.enabled:
            box = VirtualAccelerometer(scenario.accelerometer, truth.robot, *reference_motion(scenario, truth, world),
                                       world.path.q_ref_deg, scenario.payload.g_mps2, scenario.plc.period_ms / 1000.0)
        log = _loop(scenario, world, service, cfg, compensate, out_file, program, box)
    finally:
        service.stop()
        sensor.bus.shutdown()
        if out_file is not None:
            out_file.close()
    stats = service.info.stats()
    stats["status"] = "stopped"
    stats.update(dynamics_stats(service))   # as `stiffcomp run --stats-json` writes it
    extra = {"unmapped_nonzero": [], "lockstep": True, "plc_program": program.summary(log.dialled)}
    if box is not None:                 # what the box measured, low-passed, in base axes: the truth of its values
        extra["accelerometer"] = {"t": np.array([s[0] for s in box.true]), "a": np.array([s[1] for s in box.true]),
                                  "rate_hz": box.rate}
    return PassResult(log, [stats], "", compensate, extra)


def _protocol(cfg):
    from service.ati import AtiProtocol

    return AtiProtocol.from_config(cfg.source.ati)


def _loop(scenario: Scenario, world: World, service: Service, cfg, compensate: bool, out: TraceFile | None,
          program, box=None) -> PlcLog:
    """Step the service every cycle and the PLC every PLC period from WARM_UP_S before the lead to the end."""
    rmap = cfg.register_map()
    c = scenario.plc
    network = ImageNetwork(service.image, rmap, delay_ms=c.extra_delay_ms)
    plc = VirtualPlc(program, network, rmap, world.path.q_ref_deg, compensate, c.period_ms / 1000.0, world.plan,
                     {"service_timeout_ms": c.service_timeout_ms, "max_rate_deg_s": c.max_rate_deg_s}, box)
    period = cfg.cycle.period_ms / 1000.0
    plc_every = max(1, round(plc.period / period))
    t_first = world.t_start - WARM_UP_S
    n = round((world.t_end - t_first) / period) + 1
    plc.new_log(n // plc_every + 2)
    for k in range(n):
        t = t_first + k * period
        service.source.scenario_t = t
        if service.source.lead_s:
            service.source.request()
        service.work(k * period, False)
        service.info.record(0.0, None)
        if out is not None and k % 1000 == 999:
            out.write(service.trace.take())
        if k % plc_every or t < world.t_start:
            continue
        plc.cycle(t, lambda t=t: t)
    if out is not None:
        out.write(service.trace.take())
    return plc.device_log(0.0)          # no deadlines in lock step: no overruns
