"""The service: build every stage from the config, run the cycle thread and the PLC side, stop cleanly.

Start-up validates everything before anything starts: the config, the model (and whether the
real-time predictor supports all its effects), the register map and the F/T source. Then the PLC
side starts, then the cycle thread.
"""

from __future__ import annotations

import json
import logging
import sys
import threading
import time
from pathlib import Path

import numpy as np

from plc_interface.image import RegisterImage
from plc_interface.register_map import RegisterMap
from stiffness.errors import StiffnessError
from stiffness.model import StiffnessModel

from .config import ServiceConfig
from .errors import ServiceConfigError
from .pipeline import ST_STOPPED, Compensator
from .sources import make_source
from .task import CyclicTask, TaskInfo

log = logging.getLogger("stiffcomp.service")

TASK_INIT, TASK_RUN, TASK_STOP = 0, 1, 2
# the to_plc values in the order work() produces them
WORK_ORDER = ["heartbeat", "status_word", "fault_word", "task_state", "cycle_count", "exceed_count",
              "last_exec_us", "cycle_time_us", "period_jitter_us", "cycle_exceeded",
              *(f"correction_q{i}" for i in range(1, 7)),
              *(f"wrench_{c}" for c in ("fx", "fy", "fz", "mx", "my", "mz")),
              *(f"deflection_{c}" for c in ("dx", "dy", "dz", "rx", "ry", "rz"))]


class Service:
    """The assembled service.

    Parameters
    ----------
    cfg : ServiceConfig
        A validated config (`service.config.load_config`).
    """

    def __init__(self, cfg: ServiceConfig):
        self.cfg = cfg
        try:
            self.model = StiffnessModel.from_yaml(cfg.resolve(cfg.model.file))
        except StiffnessError as e:
            raise ServiceConfigError(f"{cfg.path}: model.file = {cfg.model.file!r}: {e}") from e
        self.compensator = Compensator.from_config(cfg, self.model)
        self.rmap = RegisterMap.from_yaml(cfg.resolve(cfg.plc.register_map))
        # the checks that can fail come first; the image (shared memory) and then the source open last
        names = self.rmap.codecs["to_plc"].names
        extra = [n for n in names if n not in WORK_ORDER]
        if extra:       # the map's own check has made sure every required name is there
            raise ServiceConfigError(f"{self.rmap.source}: to_plc register {extra[0]!r} is not a value the service "
                                     f"produces (known: {', '.join(WORK_ORDER)})")
        self._out_index = {n: k for k, n in enumerate(names)}
        self._out = [0.0] * len(names)
        self._order = [WORK_ORDER.index(n) for n in names]      # codec order -> work() order
        in_names = self.rmap.codecs["from_plc"].names
        self._cmd_idx, self._hb_idx = in_names.index("command_word"), in_names.index("plc_heartbeat")
        self._q_idx = [in_names.index(f"q{i}") for i in range(1, 7)]
        self._corr = [self._out_index[f"correction_q{i}"] for i in range(1, 7)]
        self.period = cfg.cycle.period_ms / 1000.0
        self.info = TaskInfo(self.period, cfg.cycle.history)
        self.plc = None
        self.task: CyclicTask | None = None
        self.failed = threading.Event()
        self.task_state = TASK_INIT
        self._closed = False
        if cfg.plc.role == "server" and cfg.plc.server_process:
            from plc_interface.shared_image import SharedRegisterImage
            self.image = SharedRegisterImage(self.rmap)
        else:
            self.image = RegisterImage(self.rmap)
        try:
            self.image.set_inputs({f"q{i + 1}": v for i, v in enumerate(cfg.plc.initial_q_deg)})
            self.source = make_source(cfg)
        except BaseException:
            if hasattr(self.image, "close"):
                self.image.close()
            raise
        self._set("cycle_time_us", self.period * 1e6)

    def _set(self, name: str, value: float) -> None:
        k = self._out_index.get(name)
        if k is not None:
            self._out[k] = value

    # -- the cycle ------------------------------------------------------------------------------
    def work(self, t: float, exceeded: bool) -> None:
        """One cycle: inputs from the image and the source, the compensator, outputs to the image."""
        image = self.image
        vals = image.in_codec.decode(image.inputs())
        q = [vals[k] for k in self._q_idx]
        reading, errors = self.source.poll(t)
        comp = self.compensator
        comp.cycle(t, reading, errors, int(vals[self._cmd_idx]), int(vals[self._hb_idx]), q, exceeded)
        info = self.info
        n = info.cycle_count + 1
        out = [n & 0xFFFF, comp.status_word, comp.faults.word, TASK_RUN, n, info.exceed_count,
               info.last_exec_s * 1e6, self.period * 1e6, info.last_jitter_s * 1e6,
               int(exceeded), *comp.correction, *comp.wrench_base, *comp.deflection]
        self._out = ordered = [out[k] for k in self._order]
        image.publish(image.out_codec.encode(ordered))

    def _on_error(self, e: BaseException) -> None:
        log.critical("the cycle stopped on an unexpected error: %r; outputs are zeroed", e)
        self.compensator.correction = [0.0] * 6
        for k in self._corr:
            self._out[k] = 0.0
        self._set("status_word", ST_STOPPED)
        self.image.publish(self.image.out_codec.encode(self._out))
        self.failed.set()

    # -- life cycle -----------------------------------------------------------------------------
    def start(self) -> None:
        self._set("task_state", TASK_INIT)
        self.image.publish(self.image.out_codec.encode(self._out))
        if self.cfg.plc.role == "server" and self.cfg.plc.server_process:
            from plc_interface.modbus_process import ModbusServerProcess
            self.plc = ModbusServerProcess(self.image, self.cfg.plc.host, self.cfg.plc.port,
                                           avoid_cpu=self.cfg.cycle.cpu)
        elif self.cfg.plc.role == "server":
            from plc_interface.modbus_server import ModbusServerThread
            self.plc = ModbusServerThread(self.image, self.cfg.plc.host, self.cfg.plc.port)
        elif self.cfg.plc.role == "client":
            from plc_interface.modbus_client import ModbusClientThread
            c = self.cfg.plc.client
            self.plc = ModbusClientThread(self.image, self.cfg.plc.host, self.cfg.plc.port, self.cfg.plc.device_id,
                                          c.period_ms / 1000.0, c.timeout_s, c.write_start, c.read_table,
                                          c.read_start)
        try:
            if self.plc is not None:
                self.plc.start()
        except BaseException:
            self.plc = None         # it cleaned up after itself
            self.stop()             # frees the image and the source
            raise
        # The Modbus thread shares the interpreter lock: a short switch interval bounds how long the
        # cycle waits for it after waking up, and stays longer than the cycle's work (so the work
        # itself is not interrupted by a forced switch).
        self._switch_interval = sys.getswitchinterval()
        sys.setswitchinterval(self.cfg.cycle.gil_switch_interval_us * 1e-6)
        self.task = CyclicTask(self.period, self.work, self.info, self._on_error, self.cfg.cycle.realtime_priority,
                               cpu=self.cfg.cycle.cpu, spin_s=self.cfg.cycle.spin_us * 1e-6)
        self.task.start()
        self.task_state = TASK_RUN
        log.info("service running: %.3f ms cycle, source %s, PLC %s", self.period * 1000, self.cfg.source.type,
                 self.cfg.plc.role if self.plc is None else f"{self.cfg.plc.role} {self.cfg.plc.host}:{self.cfg.plc.port}")

    def stop(self) -> None:
        """Ramp the correction to zero, stop the cycle, publish the stopped state, then stop the PLC side.

        Safe to call more than once, and after a failed `start`."""
        if self._closed:
            return
        self._closed = True
        if self.task is not None:
            self._ramp_down()
            self.task.stop()
            sys.setswitchinterval(self._switch_interval)
        for k in self._corr:
            self._out[k] = 0.0
        self._set("status_word", ST_STOPPED)
        self._set("task_state", TASK_STOP)
        self.image.publish(self.image.out_codec.encode(self._out))
        self.task_state = TASK_STOP
        if self.plc is not None:
            self.plc.stop()
        if hasattr(self.image, "close"):
            self.image.close()
        self.source.close()
        log.info("service stopped after %d cycles (status: stopped)", self.info.cycle_count)

    def _ramp_down(self) -> None:
        """Keep cycling in the safe state until the correction is zero (it never jumps, even on stop).

        Bounded by ``limits.fault_ramp_s`` plus a few periods (in cycles); a cycle that died cannot ramp (the PLC
        supervises status bit 6 and the heartbeat for that case, see docs/register_map.md).
        """
        comp, task, info = self.compensator, self.task, self.info
        comp.stopping = True
        ramp_s = self.cfg.limits.fault_ramp_s
        # the ramp ends after about ramp_s / period cycles (a cycle's step counts at most two periods,
        # see CorrectionLimiter); the caps allow twice that, and a loaded host that skips deadlines
        last_cycle = info.cycle_count + 2 * int(ramp_s / self.period) + 10
        deadline = time.monotonic() + 5 * ramp_s + 1.0
        while task.running and any(v != 0.0 for v in comp.correction):
            if info.cycle_count > last_cycle or time.monotonic() > deadline:
                log.warning("the correction did not reach zero within fault_ramp_s on stop: %s deg",
                            np.array2string(np.array(comp.correction), precision=4))
                break
            time.sleep(self.period)

    def log_stats(self) -> None:
        s = self.info.stats()
        c = self.compensator
        log.info("task: cycles %d, exceed %d, exec p50/p99/max %.1f/%.1f/%.1f us, jitter p99.9 %.1f us; "
                 "faults [%s]; correction %s deg", s["cycles"], s["exceed_count"], s["exec_us"]["p50"],
                 s["exec_us"]["p99"], s["exec_us"]["max"], s["period_jitter_us"]["p999"],
                 ", ".join(c.faults.active()) or "none", np.array2string(np.array(c.correction), precision=4))

    def write_stats(self, path: str | Path) -> dict:
        stats = self.info.stats()
        stats["status"] = "stopped" if self.task_state == TASK_STOP else "running"
        Path(path).write_text(json.dumps(stats, indent=2) + "\n")
        return stats
