"""The service's I/O process: started, stopped, watched, and restarted when it dies.

The two processes watch each other, so neither dies unnoticed. The main thread of the cycle process (the
caller of `Service.watch_io`, between its waits) notices an I/O process that died, logs it, latches
``io_process`` (the cycle ramps the correction to zero), and then restarts it, at most ``faults.io_restarts``
times, or fails the service (`Service.failure`; `stiffcomp run` exits 1). The I/O process exits with code 1
when the cycle process dies (`io_process.process`).
"""

from __future__ import annotations

import logging
import time

from io_base.errors import PlcError
from plc_link.contract import Fault

from .io_config import io_settings

log = logging.getLogger("stiffcomp.service")


class IoWatch:
    """The I/O process of ``service`` (a `service.app.Service`). It reads the service's config and model each
    time it starts a process, so a restart after a reload serves what the reloaded file says."""

    def __init__(self, service):
        self.service = service
        self.process = None                     # the running `io_process.process.IoProcess`, or None
        self.deaths: list[str] = []             # how each I/O process ended that died
        self.restarts = 0
        self.road_stats: dict | None = None     # the robot road's counts, from the last process that ended

    def start(self) -> None:
        """Start the I/O process the config asks for (none when it serves nothing); PlcError when it does not
        start (it cleans up after itself on error)."""
        service = self.service
        settings = io_settings(service.cfg, service.model.robot)
        if settings is None:
            return
        from io_process.process import IoProcess

        io = IoProcess(service.image, settings)
        io.start()
        log.info("I/O process running (pid %d)", io.pid)
        self.process = io

    def stop(self) -> None:
        """Stop the I/O process, keeping the robot road's counts it sends as it ends."""
        io = self.process
        if io is None:
            return
        io.stop()
        self.road_stats = io.final_stats.get("robot", self.road_stats)
        self.process = None

    def watch(self) -> str | None:
        """Check the I/O process; None while it runs (or serves again), else why the service fails.

        An I/O process that died: one error line; ``io_process`` latched (the PLC sees it once the I/O
        serves again; it stays until the PLC resets it); the correction ramps to zero; then a new I/O
        process, or, beyond ``faults.io_restarts``, the failure."""
        io = self.process
        if io is None or io.alive:
            return None
        supervisor = self.service.cycle.supervisor
        how = io.exit_reason
        self.deaths.append(how)
        limit = self.service.cfg.faults.io_restarts
        message = f"the I/O process (pid {io.pid}) died ({how}): the PLC cannot reach the service"
        log.error("%s; fault io_process latched, the correction ramps to zero", message)
        supervisor.held = ((Fault.IO_PROCESS, message),)
        self._wait_ramped()
        self.stop()
        if self.restarts >= limit:
            more = "more " if limit else ""
            return f"the I/O process died ({how}) and faults.io_restarts = {limit} allows no {more}restart"
        self.restarts += 1
        log.warning("restarting the I/O process (%d of faults.io_restarts = %d)", self.restarts, limit)
        try:
            self.start()
        except PlcError as e:
            return f"the I/O process died ({how}) and did not start again: {e}"
        supervisor.held = ()
        if self.process is not None:
            log.warning("the I/O process serves again (pid %d); fault io_process stays latched until the PLC "
                        "resets it", self.process.pid)
        return None

    def _wait_ramped(self) -> None:
        """Until the cycle has latched io_process and ramped the correction to zero (bounded as a stop is)."""
        service = self.service
        task = service.task
        deadline = time.monotonic() + 5 * service.cfg.limits.fault_ramp_s + 1.0
        while task is not None and task.running and time.monotonic() < deadline:
            if int(service.record.fault_word) & Fault.IO_PROCESS and not any(service.cycle.correction):
                return
            time.sleep(0.005)
