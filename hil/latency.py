"""Latency from a CAN frame to the register a PLC reads, measured across the real processes.

The virtual sensor numbers its samples through the force itself: sample k carries |F| = 10 + (k mod
500) N along the sensor's z axis and the sensor notes the CLOCK_MONOTONIC time it sends it. The
service runs with no filter, no spike rejection and no payload, so the wrench registers carry |F|
unchanged (rotated into base axes, which keeps the norm). The virtual PLC notes the time each read
completes; the latency of sample k is the first read showing k minus k's send time. CLOCK_MONOTONIC is
system-wide on Linux, so times from different processes compare.

What it includes: the frame's trip over udp_multicast, the wait for the service's next cycle (the
answer to one cycle's request is read in the next), the cycle's work, the wait for the PLC's next read
and the Modbus round trip.
"""

from __future__ import annotations

import copy
import multiprocessing
import tempfile
import time
from pathlib import Path

import can
import numpy as np

from hil.testing import free_port
from hil.virtual_sensor import VirtualAtiSensor
from service.ati import AtiProtocol
from service.config import load_config
from stiffness.files.yaml_schema import deep_update

from .device_log import PlcLog
from .plc_process import plc_main
from .run import (
    ServiceProcess,
    _end,
    _wait,
    free_udp_port,
    multicast_or_fail,
    pass_program,
    write_service_config,
)
from .scenario import Scenario
from .sensor import serve_until

CODES = 500
OFFSET_N = 10.0
# the service passes the sensor's numbers through unchanged
TRANSPARENT = {"filter": {"type": "none", "spike": {"max_step_N": 5000.0, "max_step_Nm": 500.0}}, "cycle": {"realtime_priority": 50},
               "gravity": {"tool": {"mass_kg": 0.0, "cog_mm": [0.0, 0.0, 0.0]}, "bias": [0.0] * 6}}


class CountingSensor(VirtualAtiSensor):
    """Answers with its sample number as the force and notes when each sample left."""

    def __init__(self, bus: can.BusABC, protocol: AtiProtocol, n_max: int = 200_000):
        super().__init__(bus, protocol, load=lambda t: np.zeros(6))
        self.sent_k = np.zeros(n_max, dtype=np.int64)
        self.sent_t = np.zeros(n_max)
        self.n = 0

    def answer(self, t: float) -> list[tuple[int, bytes]]:
        self.counter = (self.counter + 1) & 0xFFFF
        k = self.n
        frames = self.protocol.encode([0.0, 0.0, OFFSET_N + k % CODES, 0.0, 0.0, 0.0], 0, self.counter)
        if k < len(self.sent_t):
            self.sent_k[k], self.sent_t[k] = k, time.monotonic()
            self.n += 1
        return frames


def _sensor_entry(bus_kw: dict, ati: dict, out_file: str, ready, stop) -> None:
    sensor = CountingSensor(can.Bus(**bus_kw), AtiProtocol(**ati))
    try:
        serve_until(sensor, ready, stop)
    finally:
        np.savez(out_file, k=sensor.sent_k[:sensor.n], t=sensor.sent_t[:sensor.n])


def _plc_entry(scenario, robot_path, rmap, port, out_file, go, ready, program_folder) -> None:
    from stiffness.kinematics.robot import load_robot

    plc_main(scenario, load_robot(robot_path), rmap, port, False, out_file, go, ready, program_folder)


def latencies(sent_t: np.ndarray, read_t: np.ndarray, read_code: np.ndarray) -> np.ndarray:
    """Per sample seen by the PLC: its first read time minus its send time (s)."""
    by_code = [sent_t[c::CODES] for c in range(CODES)]         # sample k has code k mod CODES
    out = []
    prev = None
    for tr, code in zip(read_t, read_code):
        if code == prev:
            continue
        prev = code
        times = by_code[code]
        i = np.searchsorted(times, tr, side="right")
        if i:
            out.append(tr - times[i - 1])
    return np.array(out)


def measure(scenario: Scenario, model_path: Path, robot_path: str, seconds: float = 5.0,
            request_lead_us: float | None = None) -> dict:
    """Run sensor, service and PLC for about ``seconds``; latency percentiles in ms. ``request_lead_us``:
    the service's ``source.can.request_lead_us`` (None: the config's)."""
    with tempfile.TemporaryDirectory(prefix="stiffcomp-latency-") as tmp:
        folder = Path(tmp)
        group = f"239.74.{np.random.randint(1, 255)}.{np.random.randint(1, 255)}"
        can_port, port = free_udp_port(), free_port()
        multicast_or_fail(group, can_port)
        over = TRANSPARENT if request_lead_us is None else deep_update(
            copy.deepcopy(TRANSPARENT), {"source": {"can": {"request_lead_us": request_lead_us}}})
        cfg_path = write_service_config(scenario, model_path, folder, group, can_port, port, over)
        cfg = load_config(cfg_path)
        sc = scenario.model_copy(deep=True)
        sc.circle.feed_mm_s = 2 * np.pi * sc.circle.radius_mm / max(seconds, 0.5)
        ctx = multiprocessing.get_context("spawn")
        go = ctx.Value("d", 0.0)
        s_ready, p_ready, stop = ctx.Event(), ctx.Event(), ctx.Event()
        ati = {"base_id": cfg.source.ati.base_id, "counts_per_force": cfg.source.ati.counts_per_force,
               "counts_per_torque": cfg.source.ati.counts_per_torque}
        bus_kw = {"interface": "udp_multicast", "channel": group, "port": can_port}
        sensor = ctx.Process(target=_sensor_entry, args=(bus_kw, ati, str(folder / "sent.npz"), s_ready, stop))
        program = pass_program(cfg, None, folder)      # the library the cell loads, dialling this service
        plc = ctx.Process(target=_plc_entry, args=(sc, robot_path, cfg.register_map(), port,
                                                   str(folder / "plc.npz"), go, p_ready, str(program.folder)))
        service = ServiceProcess(cfg_path, folder)
        try:
            sensor.start()
            service.wait_running()
            plc.start()
            _wait(s_ready, sensor, "sensor")
            _wait(p_ready, plc, "PLC")
            go.value = time.monotonic() + 0.2
            plc.join(seconds + 60.0)
        finally:
            service.stop()
            stop.set()
            _end(sensor)
            _end(plc)
        stats, _ = service.result()
        with np.load(folder / "sent.npz") as z:
            sent_t = z["t"]
        log = PlcLog.load(folder / "plc.npz")
        names = cfg.register_map().codecs["to_plc"].names
        w = log.to_plc[:, [names.index(n) for n in ("wrench_fx", "wrench_fy", "wrench_fz")]]
        t_read, period = log.t_read, log.period
    code = np.rint(np.linalg.norm(w, axis=1) - OFFSET_N)
    ok = np.isfinite(code) & (code >= 0) & (code < CODES)
    lat = latencies(sent_t, t_read[ok], code[ok].astype(int)) * 1000.0
    lat = lat[lat < 1000.0]                        # a code matched across a wrap is not a latency
    return {"samples": len(lat), "p50_ms": round(float(np.percentile(lat, 50)), 3),
            "p99_ms": round(float(np.percentile(lat, 99)), 3), "max_ms": round(float(lat.max()), 3),
            "plc_period_ms": period * 1000.0, "service_cycle_ms": cfg.cycle.period_ms,
            "service_exceed_count": int(stats.get("exceed_count", 0)), "service_cycles": int(stats.get("cycles", 0))}
