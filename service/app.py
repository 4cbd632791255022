"""The service: build every stage from the config, run the cycle and the I/O process, stop cleanly.

Two processes, as TwinCAT separates its real-time task from the ADS router and the Modbus server:

* this process runs the 1 ms cycle (`CyclicTask`) and nothing else while it runs: no server, no notifier
  thread, no file or socket I/O but the sensor's non-blocking reads; log lines only on state changes;
* the I/O process (`plc_interface.io_process.IoProcess`) serves Modbus TCP (or the Modbus client
  role), ADS and the robot road on one asyncio loop (`service.io_config`).

They meet only in the shared `ProcessImage`, which neither side ever waits on. Each cycle the service
builds the contract's `ToPlc` record by name (`plc_interface.contract.Producer`) and publishes it.

The two processes watch each other, so neither dies unnoticed. The main thread of this process (the caller of
`Service.watch_io`, between its waits) notices an I/O process that died, logs it, latches ``io_process`` (the
cycle ramps the correction to zero), and then restarts it, at most ``faults.io_restarts`` times, or fails the
service (`failure`; `stiffcomp run` exits 1). The I/O process exits with code 1 when this one dies.

Start-up validates everything first: the config, the model (and whether the real-time predictor supports all its
effects), the register map against the contract and the F/T source. Then the I/O process starts, then the cycle.
With ``cycle.compiled`` the signal path is compiled (`service.kernel`: numba loads it from its disk cache, or
compiles it the first time) in a thread that runs while the I/O process starts, so the first cycle never waits
for a compiler; a model with no compiled form runs on the Python path (one log line).
"""

from __future__ import annotations

import json
import logging
import threading
import time
from pathlib import Path

import numpy as np

from plc_interface.contract import Fault, FromPlc, Producer, TaskState, TaskValues, ToPlc, stopped
from plc_interface.errors import PlcError
from plc_interface.image import ProcessImage
from plc_interface.io_server import IoSettings

from .compensation import load_model
from .config import ServiceConfig
from .cycle_rules import task_row
from .errors import ServiceConfigError
from .io_config import io_settings
from .pipeline import Cycle
from .sources import make_source
from .task import CyclicTask, TaskInfo
from .trace import TraceOptions, TraceRing, TraceWriter
from .value_vector import Values

log = logging.getLogger("stiffcomp.service")

_RUN = int(TaskState.RUN)


class Service:
    """The assembled service.

    Parameters
    ----------
    cfg : ServiceConfig
        A validated config (`service.config.load_config`).
    trace : TraceOptions, optional
        Record every cycle to a file, written by a process of its own (`service.trace`); off by default.
    source : FtSource, optional
        The F/T source to read instead of the config's ``source`` (the lock-step HIL hands its virtual
        sensor's frames so, `hil.lockstep`).
    """

    def __init__(self, cfg: ServiceConfig, trace: TraceOptions | None = None, source=None):
        if trace is not None:
            trace.check()
        self.cfg = cfg
        self.trace_options = trace
        self.trace: TraceRing | None = None
        self.trace_writer: TraceWriter | None = None
        self.trace_counts: dict[str, int] | None = None
        self.model = load_model(cfg)
        self.rmap = cfg.register_map()
        # the cycle's values as one vector (`service.value_vector`): the compiled service packs its record from it
        self.values = Values(len(FromPlc._fields) + len(self.rmap.codecs["to_plc"].names))
        self.cycle = Cycle.from_config(cfg, self.model, self.values.signals)
        dyn = self.cycle.compensator.dynamics
        for name in (dyn.plc_values() if dyn is not None else []):
            if name not in self.rmap.codecs["from_plc"].index:
                raise ServiceConfigError(f"{cfg.path}: dynamics.feedforward reads {name} from the PLC, but "
                                         f"plc.register_map = {cfg.plc.register_map} has no register {name} "
                                         "(docs/register_map.md, \"The plan\")")
        self.period = cfg.cycle.period_ms / 1000.0
        self.info = TaskInfo(self.period, cfg.cycle.history)
        self.produce = Producer()
        self.produce.check(self._task_values(TaskState.INIT), self.cycle.signals())
        self._to_plc = self.produce.indices(self.values.slots)     # TO_PLC's values in the vector
        self._packers = None            # (image, trace) packers of the compiled service (`_compile`), None: records
        self._steady = None             # its steady cycle (`service.steady`)
        self.io = None
        self.task: CyclicTask | None = None
        self.failed = threading.Event()
        self.failure: str | None = None         # why the service failed, in words (--stats-json)
        self.io_deaths: list[str] = []          # how each I/O process ended that died
        self.io_restarts = 0
        self.road_stats: dict | None = None     # the robot road's counts, from the last I/O process that ended
        self._closed = False
        self._stop_at: tuple[int, float] | None = None       # (last cycle, last time) of the stop ramp
        self.pending: list = []         # a prepared reload the cycle takes (pop, atomic) and swaps in (service.reload)
        self.reload_attempts = 0
        self.last_reload = None         # the outcome of the last reload (service.reload.Outcome)
        # the checks that can fail come first; the image (shared memory) and then the source open last
        self.image = ProcessImage(self.rmap)
        try:
            self.image.write_values({f"q{i + 1}": v for i, v in enumerate(cfg.plc.initial_q_deg)})
            self.source = make_source(cfg) if source is None else source
        except BaseException:
            self.image.close()
            raise
        self.trace = TraceRing() if trace is not None else None
        self.record = self.produce(self._task_values(TaskState.INIT), self.cycle.signals())
        self.compile_s: float | None = None     # how long the compiled path took to be ready (s)
        self._compiling = None
        if cfg.cycle.compiled:
            self._compiling = threading.Thread(target=self._compile, name="stiffcomp-compile", daemon=True)
            self._compiling.start()

    def wait_compiled(self) -> None:
        """Until the compiled signal path is ready (or the Python path stays): before the first cycle."""
        if self._compiling is not None:
            self._compiling.join()              # loaded from numba's cache in well under a second
            self._compiling = None

    def _compile(self) -> None:
        """The compiled signal path (a thread of the start-up, beside the I/O process's start)."""
        t0 = time.perf_counter()
        try:
            self.cycle.compensator.compile()
        except Exception as e:  # noqa: BLE001 - any reason (no compiled form, no numba) leaves the Python path
            log.warning("the cycle runs on the Python path: %s", e)
            return
        self._packers, self._steady = self.values.compiled(self, self._to_plc)
        self.compile_s = time.perf_counter() - t0       # `start` says it, once the I/O process serves

    def _task_tuple(self, state: int) -> list[float]:
        """The task's counters of the cycle now, in `TaskValues`' order, also into the values' task part
        (`service.cycle_rules.task_row`)."""
        info, v = self.info, self.values.task
        task_row(v, info.cycle_count + (state == _RUN), state, info.exceed_count, info.last_exec_s * 1e6,
                 self.period * 1e6, info.last_jitter_s * 1e6, info.last_exceeded)
        return v.tolist()

    def _task_values(self, state: TaskState) -> TaskValues:
        return TaskValues._make(self._task_tuple(int(state)))

    @property
    def record(self) -> ToPlc:
        """The last cycle's `ToPlc` record (the compiled service builds it when asked, from `values`)."""
        if self._record is None:
            self._record = ToPlc._make(self.values.V[self._to_plc].tolist())
        return self._record

    @record.setter
    def record(self, record: ToPlc) -> None:
        self._record = record

    # -- the cycle ------------------------------------------------------------------------------
    def work(self, t: float, exceeded: bool) -> bool:
        """One cycle: inputs from the image and the source, the cycle, the record to the image.

        Returns False when a requested stop has ramped the correction to zero (the task then ends)."""
        steady = self._steady
        if self.pending:                # a reload, between two cycles: references and a few floats
            try:
                swap = self.pending.pop()
            except IndexError:          # the main thread withdrew it meanwhile
                swap = None
            if swap is not None:
                swap(self.cycle, self.source)
        elif (steady is not None and steady.call is not None and not exceeded and not self.cycle.supervisor.held
              and not (self.task is not None and self.task.stop_requested)):
            reading, errors = self.source.poll(t)      # the steady cycle (`service.steady`): one compiled call
            if not errors and steady.run(t, reading):
                if self.trace is not None:
                    self.trace.put_with(self._packers[1], t)
                return True
            return self._glue(t, exceeded, reading, errors)
        return self._glue(t, exceeded, *self.source.poll(t))

    def _glue(self, t: float, exceeded: bool, reading, errors) -> bool:
        """A cycle of the Python glue (`Cycle.advance`) with this cycle's sample and the source's problems."""
        inp = self.image.inputs()
        cyc = self.cycle
        if self.task is not None and self.task.stop_requested and not cyc.stopping:
            self._begin_stop(t)
        q = [inp.q1, inp.q2, inp.q3, inp.q4, inp.q5, inp.q6]
        cyc.advance(t, reading, errors, int(inp.command_word), int(inp.plc_heartbeat), q, exceeded,
                    int(inp.payload_index), inp)
        go_on = not (cyc.stopping and self._stop_done(t))
        packers = self._packers
        if packers is None or not go_on:
            sig = cyc.signals()
            self.record = record = self.produce(self._task_values(TaskState.RUN), sig)
            if not go_on:
                self.record = record = stopped(record)
            self.image.publish(record, time.time_ns())
            if self.trace is not None:
                self.trace.put_cycle(t, q, sig, record.task_state)
            return go_on
        # the compiled service: the values into the vector, then one compiled call packs the PLC's block
        task = self._task_tuple(_RUN)
        self._record = None
        if not self.image.publish_with(packers[0], time.time_ns(), task[4], task[6]):
            self.image.publish(self.record, time.time_ns())     # a value beyond float32: struct says which
        if packers[1] is not None:
            self.values.put_t_q(t, q)
            self.trace.put_with(packers[1], t)
        self._steady.export()
        return True

    def _begin_stop(self, t: float) -> None:
        """Ramp to zero (it never jumps, even on stop), bounded in cycles and loosely in time: the ramp ends
        after about fault_ramp_s / period cycles (a step counts at most two periods, see CorrectionLimiter);
        the caps allow twice that, and a loaded host that skips deadlines."""
        self.cycle.stopping = True
        ramp_s = self.cfg.limits.fault_ramp_s
        self._stop_at = (self.info.cycle_count + 2 * int(ramp_s / self.period) + 10, t + 5 * ramp_s + 1.0)

    def _stop_done(self, t: float) -> bool:
        correction = self.cycle.correction
        if not any(v != 0.0 for v in correction):
            return True
        last_cycle, last_t = self._stop_at
        if self.info.cycle_count > last_cycle or t > last_t:
            log.warning("the correction did not reach zero within fault_ramp_s on stop: %s deg",
                        np.array2string(np.array(correction), precision=4))
            return True
        return False

    def _on_error(self, e: BaseException) -> None:
        log.critical("the cycle stopped on an unexpected error: %r; outputs are zeroed", e)
        self.failure = f"the cycle stopped on an unexpected error: {e!r}"
        self.cycle.compensator.correction = [0.0] * 6
        self.record = stopped(self.record)._replace(task_state=self.record.task_state)
        self.image.publish(self.record, time.time_ns())
        self.failed.set()

    # -- life cycle -----------------------------------------------------------------------------
    def start(self) -> None:
        self.image.publish(self.record, time.time_ns())
        if self.trace is not None:
            self.trace_writer = TraceWriter(self.trace, self.trace_options)
            try:
                self.trace_writer.start()
            except BaseException:
                self.trace_writer = None
                self.stop()
                raise
        settings = io_settings(self.cfg, self.model.robot)
        if settings is not None:
            try:
                self.io = self._start_io(settings)
            except BaseException:
                self.stop()             # frees the image and the source (the I/O process cleaned up itself)
                raise
        self.wait_compiled()
        if self.compile_s is not None:  # said only now: a start that failed before this line says nothing ready
            log.info("compiled signal path ready in %.2f s", self.compile_s)
        self.task = CyclicTask(self.period, self.work, self.info, self._on_error, self.cfg.cycle.realtime_priority,
                               cpu=self.cfg.cycle.cpu, spin_s=self.cfg.cycle.spin_us * 1e-6,
                               lock_memory=self.cfg.cycle.lock_memory, prepare=self.source.request,
                               lead_s=self.source.lead_s, cpu_latency_us=self.cfg.cycle.cpu_latency_us)
        self.task.start()
        p = self.cfg.plc
        a = self.cfg.ads
        r = self.cfg.robot
        log.info("service running: %.3f ms cycle, source %s, PLC %s%s%s", self.period * 1000, self.cfg.source.type,
                 p.role if self.io is None else p.served(),
                 f", ADS {a.host}:{a.port} ({a.net_id}:{a.ams_port})" if a.enabled else "",
                 f", robot {r.served()}" if r.enabled else "")

    def stop(self) -> None:
        """Ask the cycle to ramp the correction to zero and end, publish the stopped state, stop the I/O.

        Safe to call more than once, and after a failed `start`."""
        if self._closed:
            return
        self._closed = True
        task = self.task
        if task is not None and task.running:
            task.request_stop()
            if not task.join(5 * self.cfg.limits.fault_ramp_s + 5.0):
                log.error("the cycle did not end after the stop request")
        if self.task_state != TaskState.STOP:      # a cycle that never ran or died still leaves the stopped state
            self.record = stopped(self.record)
            self.image.publish(self.record, time.time_ns())
        if self.io is not None:
            self._stop_io(self.io)
        if self.trace_writer is not None:
            self.trace_counts = self.trace_writer.stop()
        if self.trace is not None:
            self.trace.close()
        if self._steady is not None:        # its call holds arrays over the image's memory, unmapped by close
            self._steady.call = None
        self.image.close()
        self.source.close()
        log.info("service stopped after %d cycles (status: stopped)" if task is not None else
                 "the service did not start: %d cycles ran (status: stopped)", self.info.cycle_count)

    def _start_io(self, settings: IoSettings):
        """A running I/O process serving ``settings`` on this image (it cleans up after itself on error)."""
        from plc_interface.io_process import IoProcess

        io = IoProcess(self.image, settings)
        io.start()
        log.info("I/O process running (pid %d)", io.pid)
        return io

    def _stop_io(self, io) -> None:
        io.stop()
        self.road_stats = io.final_stats.get("robot", self.road_stats)

    def _fail(self, reason: str) -> bool:
        """The service failed for ``reason`` (`failure`, ``--stats-json``; `stiffcomp run` exits 1)."""
        self.failure = reason
        log.critical("%s: the service stops (exit code 1)", reason)
        self.failed.set()
        return False

    # -- the watch on the I/O process ------------------------------------------------------------
    def watch_io(self) -> bool:
        """Check the I/O process (the main thread calls this between its waits); False when the service
        must stop because it failed (`failure` says why).

        An I/O process that died: one error line; ``io_process`` latched (the PLC sees it once the I/O
        serves again; it stays until the PLC resets it); the correction ramps to zero; then a new I/O
        process, or, beyond ``faults.io_restarts``, the failure."""
        io = self.io
        if io is None or self._closed or io.alive:
            return self.failure is None
        how = io.exit_reason
        self.io_deaths.append(how)
        limit = self.cfg.faults.io_restarts
        message = f"the I/O process (pid {io.pid}) died ({how}): the PLC cannot reach the service"
        log.error("%s; fault io_process latched, the correction ramps to zero", message)
        self.cycle.supervisor.held = ((Fault.IO_PROCESS, message),)
        self._wait_ramped_for_io()
        self._stop_io(io)
        self.io = None
        if self.io_restarts >= limit:
            return self._fail(f"the I/O process died ({how}) and faults.io_restarts = {limit} allows no "
                              f"{'more ' if limit else ''}restart")
        self.io_restarts += 1
        log.warning("restarting the I/O process (%d of faults.io_restarts = %d)", self.io_restarts, limit)
        try:
            self.io = self._start_io(io_settings(self.cfg, self.model.robot))
        except PlcError as e:
            return self._fail(f"the I/O process died ({how}) and did not start again: {e}")
        self.cycle.supervisor.held = ()
        log.warning("the I/O process serves again (pid %d); fault io_process stays latched until the PLC resets "
                    "it", self.io.pid)
        return True

    def _wait_ramped_for_io(self) -> None:
        """Until the cycle has latched io_process and ramped the correction to zero (bounded as the stop is)."""
        task = self.task
        deadline = time.monotonic() + 5 * self.cfg.limits.fault_ramp_s + 1.0
        while task is not None and task.running and time.monotonic() < deadline:
            if int(self.record.fault_word) & Fault.IO_PROCESS and not any(self.cycle.correction):
                return
            time.sleep(0.005)

    def on_hangup(self):
        """SIGHUP (and `stiffcomp reload`): reload the config file (`service.reload.reload`; one log line,
        the outcome returned). The correction goes on throughout; nothing is applied from a refused file."""
        from .reload import reload

        self.reload_attempts += 1
        self.last_reload = reload(self)
        return self.last_reload

    @property
    def task_state(self) -> TaskState:
        return TaskState(int(self.record.task_state))

    def log_stats(self) -> None:
        s = self.info.stats()
        c = self.cycle
        log.info("task: cycles %d, exceed %d, exec p50/p99/max %.1f/%.1f/%.1f us, jitter p99.9 %.1f us; "
                 "faults [%s]; correction %s deg", s["cycles"], s["exceed_count"], s["exec_us"]["p50"],
                 s["exec_us"]["p99"], s["exec_us"]["max"], s["period_jitter_us"]["p999"],
                 ", ".join(c.faults.active()) or "none", np.array2string(np.array(c.correction), precision=4))

    def write_stats(self, path: str | Path) -> dict:
        stats = self.info.stats()
        stats["status"] = "stopped" if self.task_state == TaskState.STOP else "running"
        stats["failure"] = self.failure
        stats["io_process"] = {"deaths": self.io_deaths, "restarts": self.io_restarts}
        if self.cfg.robot.enabled:
            stats["robot"] = self.road_stats
        if self.trace_counts is not None:
            stats["trace"] = {"file": str(self.trace_options.path), **self.trace_counts}
        Path(path).write_text(json.dumps(stats, indent=2) + "\n")
        return stats
