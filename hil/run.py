"""One HIL pass: the service, the virtual sensor and the virtual PLC, each in its own process.

    virtual sensor --CAN (udp_multicast)--> service (`stiffcomp run`) <--Modbus TCP-- virtual PLC
         ^ process force of the world                                      | q_cmd, logged
                                                         robot stub (truth model) -> actual TCP

The three processes share nothing but the protocols and the start time of the cut (a
multiprocessing Value holding a CLOCK_MONOTONIC time, which is system-wide on Linux). Every run
picks its own multicast group, UDP port, Modbus port and ADS port, so parallel runs never collide. Every
process is stopped and joined on every path (try/finally).
"""

from __future__ import annotations

import http.client
import json
import multiprocessing
import random
import signal
import socket
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pymodbus.client import ModbusTcpClient

from hil.cell_network import PlcFaults
from hil.testing import free_port, write_config
from io_process.endpoints import read_health
from plc_link.contract import TaskState
from plc_link.register_map import RegisterMap
from service.config import load_config
from stiffness.files.yaml_schema import deep_update
from stiffness.kinematics.robot import load_robot
from stiffness.model.stiffness_model import StiffnessModel

from .accelerometer import reference_motion, register_map_with_accelerometer, sampling_rate
from .device_log import PlcLog, RobotLog
from .errors import HilError
from .multicast import MulticastError, check_multicast
from .plc_process import plc_main
from .plc_program import PlcProgram, generate_program
from .priority import ROAD_IO_FIFO
from .scenario import ROOT, Scenario
from .sensor import sensor_main
from .world import World

START_TIMEOUT_S = 90.0


@dataclass
class Faults:
    """Faults to inject in one pass (times in s since the cut started)."""

    sensor: tuple[str, float] | None = None          # ("stop" | "babble", t)
    plc: PlcFaults | None = None
    service_restart_at: float | None = None
    service_down_s: float = 0.3


@dataclass
class PassResult:
    """What one pass left: the device's log (the virtual PLC's, or the virtual robot's on the robot road), the
    service's stats and log, what was refused."""

    log: PlcLog | RobotLog
    stats: list[dict]
    service_log: str
    compensate: bool
    extra: dict = field(default_factory=dict)


def free_udp_port() -> int:
    return free_port(socket.SOCK_DGRAM)


def write_service_config(scenario: Scenario, model_path: Path, folder: Path, group: str, can_port: int,
                         modbus_port: int, overrides: dict | None = None) -> Path:
    """The scenario's service config with this run's model, bus and ports (its ADS server's too), and
    ``overrides``."""
    run = {"model": {"file": str(Path(model_path).resolve())}, "plc": {"port": modbus_port}, "ads": {"port": free_port()},
           "source": {"can": {"channel": group, "options": {"port": can_port}}}}
    merged = deep_update(run, overrides or {})
    path = write_config(folder, merged, source=scenario.resolve(scenario.service))
    box = scenario.accelerometer
    if not box.enabled:
        return path
    cfg = load_config(path)          # the box's values bound in the map the pass uses, and the service reading them
    merged = deep_update(merged, {
        "plc": {"register_map": str(register_map_with_accelerometer(cfg, folder))},
        "accelerometer": {"enabled": True, "mount": {"rpy_deg": list(box.mount_rpy_deg)},
                          "timeout_ms": max(20.0, 4000.0 / sampling_rate(box, scenario.plc.period_ms / 1000.0))}})
    return write_config(folder, merged, source=scenario.resolve(scenario.service))


class ServiceProcess:
    """`stiffcomp run` as a child process; its log goes to a file (a pipe could fill and block it)."""

    def __init__(self, config: Path, folder: Path, index: int = 0, log_level: str = "INFO",
                 new_session: bool = False, trace: Path | None = None):
        self.config = config
        self.stats = folder / f"service_stats_{index}.json"
        self.log_path = folder / f"service_{index}.log"
        self._log = self.log_path.open("w")
        extra = [] if trace is None else ["--trace", str(Path(trace).resolve())]
        self.proc = subprocess.Popen([sys.executable, "-m", "tools.cli", "run", "--config", str(config),
                                      "--stats-json", str(self.stats), "--log-level", log_level, *extra], cwd=ROOT,
                                     stdout=subprocess.DEVNULL, stderr=self._log, start_new_session=new_session)

    def wait_running(self, timeout: float = START_TIMEOUT_S) -> None:
        """Until the service's ``GET /health`` reports its task running (task state RUN). Healthy or not:
        before the PLC connects, a heartbeat fault may be latched, and the PLC resets it."""
        deadline = time.monotonic() + timeout
        mon = load_config(self.config).monitoring            # read while the service starts
        if not mon.enabled:
            raise HilError(f"{self.config}: monitoring.enabled is false: the HIL waits for the service's /health")
        self.health_at = ("127.0.0.1", mon.port)
        while time.monotonic() < deadline:
            if self.proc.poll() is not None:
                raise HilError(f"the service exited with {self.proc.returncode}:\n{self.log_path.read_text()}")
            try:
                if read_health(*self.health_at, timeout_s=1.0).get("task_state") == TaskState.RUN:
                    return
            except (OSError, http.client.HTTPException, ValueError):
                pass                                    # not serving yet
            time.sleep(0.05)
        raise HilError(f"the service did not report its task running at {self.health_at[0]}:{self.health_at[1]}"
                       f"/health within {timeout:g} s")

    def stop(self) -> None:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait(10)
        self._log.close()

    def result(self) -> tuple[dict, str]:
        stats = json.loads(self.stats.read_text()) if self.stats.exists() else {}
        return stats, self.log_path.read_text()


def _wait(event, proc, what: str, timeout: float = START_TIMEOUT_S) -> None:
    deadline = time.monotonic() + timeout
    while not event.wait(0.05):
        if not proc.is_alive():
            raise HilError(f"the {what} process exited with {proc.exitcode} before it was ready")
        if time.monotonic() > deadline:
            raise HilError(f"the {what} process was not ready in time")


def run_pass(scenario: Scenario, truth: StiffnessModel, model_path: Path, compensate: bool, folder: Path,
             faults: Faults | None = None, service_overrides: dict | None = None,
             trace: Path | None = None, robot_interface: str | None = None,
             robot_section: dict | None = None, plc_program: Path | None = None) -> PassResult:
    """Run the closed loop once in real time; returns the PLC's log and the service's stats. ``trace``: the
    service records every cycle there (`stiffcomp run --trace`). ``robot_interface`` (``kuka_rsi``,
    ``abb_egm``): the robot road instead of the PLC: a virtual robot of that interface (`hil.robot_process`)
    drives the cut, the service has no PLC (``plc.role: none``) and the pass's log is the robot's; the
    interface's sub-section is ``robot_section``, by default the shipped robot config's (`shipped_robot_section`).
    ``plc_program``: the folder of the TwinCAT program the virtual PLC runs (by default the library generated for
    this pass's config, `hil.plc_program.generate_program`)."""
    faults = faults or Faults()
    folder.mkdir(parents=True, exist_ok=True)
    group = f"239.74.{random.randint(1, 254)}.{random.randint(1, 254)}"
    can_port, modbus_port = free_udp_port(), free_port()
    multicast_or_fail(group, can_port)      # before any process starts: one line with what to run
    if robot_interface is not None:
        section = robot_section if robot_section is not None else shipped_robot_section(robot_interface)
        road = {"plc": {"role": "none", "enable_on_start": compensate},      # uncompensated: never enabled
                "robot": {"interface": robot_interface, "port": free_udp_port(), "host": "127.0.0.1",
                          "peer": "127.0.0.1", "realtime_priority": ROAD_IO_FIFO, robot_interface: section}}
        service_overrides = deep_update(road, service_overrides or {})
    cfg_path = write_service_config(scenario, model_path, folder, group, can_port, modbus_port, service_overrides)
    cfg = load_config(cfg_path)
    robot_path = truth.robot.source
    ctx = multiprocessing.get_context("spawn")
    go = ctx.Value("d", 0.0)
    sensor_ready, plc_ready, stop = ctx.Event(), ctx.Event(), ctx.Event()
    out_file = folder / f"{'plc' if robot_interface is None else 'robot'}_{'comp' if compensate else 'uncomp'}.npz"
    services = [ServiceProcess(cfg_path, folder, 0, trace=trace)]
    ati = {"base_id": cfg.source.ati.base_id, "counts_per_force": cfg.source.ati.counts_per_force,
           "counts_per_torque": cfg.source.ati.counts_per_torque}
    bus_kw = {"interface": "udp_multicast", "channel": group, "port": can_port}
    sensor = ctx.Process(target=_sensor_entry, name="hil-sensor", args=(
        scenario, robot_path, bus_kw, ati, go, sensor_ready, stop, faults.sensor,
        truth.input_map()))
    program = None
    if robot_interface is None:
        program = pass_program(cfg, plc_program, folder)
        motion = reference_motion(scenario, truth, World(scenario, truth.robot)) if scenario.accelerometer.enabled else None
        plc = ctx.Process(target=_plc_entry, name="hil-plc", args=(
            scenario, robot_path, cfg.register_map(), modbus_port, compensate, str(out_file), go,
            plc_ready, str(program.folder), faults.plc, cfg.ads.port if cfg.ads.enabled else None, motion))
    else:
        plc = ctx.Process(target=_robot_entry, name="hil-robot", args=(
            scenario, robot_path, cfg.robot, cfg.robot.port, str(out_file), go, plc_ready))
    procs = [sensor, plc]
    try:
        sensor.start()
        plc.start()                          # both import while the service starts; the PLC retries its connect
        services[0].wait_running()
        _wait(sensor_ready, sensor, "sensor")
        _wait(plc_ready, plc, "PLC")
        t0 = time.monotonic() + 0.2
        go.value = t0
        if faults.service_restart_at is not None:
            _sleep_until(t0 + faults.service_restart_at)
            services[-1].stop()
            time.sleep(faults.service_down_s)
            services.append(ServiceProcess(cfg_path, folder, len(services)))
            services[-1].wait_running()
        world_len = scenario.circle.lead_s + 2 * np.pi * scenario.circle.radius_mm / scenario.circle.feed_mm_s
        plc.join(world_len + scenario.circle.tail_s + 60.0)
        if plc.exitcode != 0:
            raise HilError(f"the {'PLC' if robot_interface is None else 'robot'} process ended with {plc.exitcode}")
        unmapped = probe_unmapped(modbus_port, cfg.register_map()) if cfg.plc.role == "server" else []
    finally:
        stop.set()
        for s in services:
            s.stop()
        for p in procs:
            _end(p)
    results = [s.result() for s in services]
    extra = {"unmapped_nonzero": unmapped}
    if program is None:
        log = RobotLog.load(out_file)
    else:
        log = PlcLog.load(out_file)
        extra["plc_program"] = program.summary(log.dialled)
    return PassResult(log, [r[0] for r in results], "\n".join(r[1] for r in results), compensate, extra)


def pass_program(cfg, plc_program: Path | None, folder: Path) -> PlcProgram:
    """The program of a pass: ``plc_program``'s, or the library generated for ``cfg`` into ``folder``/plc."""
    if plc_program is not None:
        return PlcProgram(plc_program)
    return generate_program(cfg.register_map(), cfg.plc.port, cfg.plc.device_id, folder / "plc")


def shipped_robot_section(interface: str) -> dict:
    """The ``robot.<interface>`` sub-section of the shipped config/robot_<interface>.yaml: the HIL's virtual robot
    is set up as the shipped robot side is (EGM: path mode at 48 ms). An interface without a shipped config: its
    model's defaults, which its declaration makes the robot side's it ships."""
    from stiffness.files.yaml_syntax import read_yaml

    shipped = ROOT / "config" / f"robot_{interface}.yaml"
    return dict(read_yaml(shipped)["robot"][interface]) if shipped.exists() else {}


def probe_unmapped(port: int, rmap: RegisterMap) -> list[str]:
    """Read both blocks whole from the running service; name every nonzero word that no register of
    the map covers (what a write outside the map, or a stray publish, would leave)."""
    mapped = {(r.table, a) for r in rmap.registers for a in range(r.address, r.address + r.count)}
    found = []
    with ModbusTcpClient("127.0.0.1", port=port, timeout=2.0, retries=1) as c:
        if not c.connect():
            raise HilError(f"cannot reach the service at 127.0.0.1:{port} to probe the registers")
        for b in rmap.blocks.values():
            read = c.read_input_registers if b.table == "input_registers" else c.read_holding_registers
            for start in range(b.start, b.start + b.size, 125):
                n = min(125, b.start + b.size - start)
                r = read(start, count=n)
                if r.isError():
                    raise HilError(f"the service refused a read of {b.table} {start:#06x}+{n}: {r}")
                found += [f"{b.table} {start + k:#06x} = {v:#06x}" for k, v in enumerate(r.registers)
                          if v and (b.table, start + k) not in mapped]
    return found


def multicast_or_fail(group: str, port: int) -> None:
    """HilError in one line (what to run) where this host cannot carry udp_multicast (`hil.multicast`)."""
    try:
        check_multicast(group, port)
    except MulticastError as e:
        raise HilError(str(e)) from None


def _end(p) -> None:
    """Join a child process; terminate, then kill, one that does not end."""
    if p.pid is None:
        return
    p.join(10)
    if p.is_alive():
        p.terminate()
        p.join(5)
    if p.is_alive():
        p.kill()
        p.join(5)


def _sleep_until(t: float) -> None:
    while (d := t - time.monotonic()) > 0:
        time.sleep(min(d, 0.05))


def _sensor_entry(scenario, robot_path, bus_kw, ati, go, ready, stop, fault, input_map) -> None:
    sensor_main(scenario, load_robot(robot_path), bus_kw, ati, go, ready, stop, fault, input_map)


def _robot_entry(scenario, robot_path, settings, port, out_file, go, ready) -> None:
    from .robot_process import robot_main

    robot_main(scenario, load_robot(robot_path), settings, port, out_file, go, ready)


def _plc_entry(scenario, robot_path, rmap, port, compensate, out_file, go, ready, program, faults, ads_port,
               motion) -> None:
    plc_main(scenario, load_robot(robot_path), rmap, port, compensate, out_file, go, ready, program, faults,
             ads_port=ads_port, motion=motion)
