"""The service: build every stage from the config, run the cycle and the I/O process, stop cleanly.

Two processes, as TwinCAT separates its real-time task from the ADS router and the Modbus server:

* this process runs the 1 ms cycle (`CyclicTask`) and nothing else while it runs: no server, no notifier
  thread, no file or socket I/O but the sensor's non-blocking reads; log lines only on state changes;
* the I/O process (`io_process.process.IoProcess`) serves Modbus TCP (or the Modbus client
  role), ADS and the robot road on one asyncio loop (`service.io_config`).

They meet only in the shared `ProcessImage`, which neither side ever waits on. Each cycle the service
builds the contract's `ToPlc` record by name (`plc_link.contract.Producer`) and publishes it.

The two processes watch each other, so neither dies unnoticed: the main thread of this process calls
`Service.watch_io` between its waits, which restarts an I/O process that died or fails the service
(`service.io_watch`). The I/O process exits with code 1 when this one dies.

Start-up validates everything first: the config, the model (and whether the real-time predictor supports all its
effects), the register map against the contract and the F/T source (`service.startup`). Then the I/O process
starts, then the cycle. With ``cycle.compiled`` the signal path compiles in a thread meanwhile
(`service.startup.Compiling`), so the first cycle never waits for a compiler.

Each part of the service that is not the cycle has a module of its own: the I/O process's start, stop and watch
(`service.io_watch`), the start-up's checks and compiler (`service.startup`), a reload (`service.reload`), the
statistics it reports (`service.run_stats`).
"""

from __future__ import annotations

import logging
import threading
import time
from pathlib import Path

import numpy as np

from plc_link.contract import FromPlc, Producer, TaskState, TaskValues, ToPlc, stopped
from plc_link.image import ProcessImage

from .compensation import load_model
from .config import ServiceConfig
from .cycle_rules import task_row
from .io_watch import IoWatch
from .pipeline import Cycle
from .run_stats import log_stats, write_stats
from .sources import make_source
from .startup import Compiling, check_plc_values
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
        check_plc_values(cfg, self.cycle, self.rmap)
        self.period = cfg.cycle.period_ms / 1000.0
        self.info = TaskInfo(self.period, cfg.cycle.history)
        self.produce = Producer()
        self.produce.check(self._task_values(TaskState.INIT), self.cycle.signals())
        self.to_plc_slots = self.produce.indices(self.values.slots)     # TO_PLC's values in the vector
        self._packers = None            # (image, trace) packers of the compiled service, None: records
        self._steady = None             # its steady cycle (`service.steady`)
        self.io_watch = IoWatch(self)
        self.task: CyclicTask | None = None
        self.failed = threading.Event()
        self.failure: str | None = None         # why the service failed, in words (--stats-json)
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
        self._compiling = Compiling(self) if cfg.cycle.compiled else None

    def wait_compiled(self) -> None:
        """Until the compiled signal path is ready (or the Python path stays): before the first cycle."""
        compiling, self._compiling = self._compiling, None
        if compiling is not None:
            compiling.join()
            self._packers, self._steady, self.compile_s = compiling.packers, compiling.steady, compiling.seconds

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
            self._record = ToPlc._make(self.values.V[self.to_plc_slots].tolist())
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
        try:
            self.io_watch.start()
        except BaseException:
            self.stop()                 # frees the image and the source (the I/O process cleaned up itself)
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
                 p.role if self.io_watch.process is None else p.served(),
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
        self.io_watch.stop()
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

    def _fail(self, reason: str) -> bool:
        """The service failed for ``reason`` (`failure`, ``--stats-json``; `stiffcomp run` exits 1)."""
        self.failure = reason
        log.critical("%s: the service stops (exit code 1)", reason)
        self.failed.set()
        return False

    def watch_io(self) -> bool:
        """Check the I/O process (the main thread calls this between its waits; `service.io_watch`); False
        when the service must stop because it failed (`failure` says why)."""
        if not self._closed:
            why = self.io_watch.watch()
            if why is not None:
                return self._fail(why)
        return self.failure is None

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
        """One log line of the task's statistics (`service.run_stats.log_stats`)."""
        log_stats(self)

    def write_stats(self, path: str | Path) -> dict:
        """The ``--stats-json`` file (`service.run_stats.write_stats`)."""
        return write_stats(self, path)
