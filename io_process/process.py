"""The I/O process: `IoServer` in a process of its own, so the cycle keeps an interpreter to itself.

The child is started with the spawn method (nothing inherited from a threaded parent), is kept off
the cycle's CPU when the cycle is pinned, logs to the parent's stderr in the parent's format, and
stops when the parent sets its stop event.

Signals. SIGINT, SIGTERM and SIGHUP are the cycle process's to handle (Ctrl-C and a terminal or
systemd send them to the whole process group): the child ignores them from its first instruction on
(they are ignored while it is spawned, and an ignored disposition survives exec), so Ctrl-C on
``make run`` prints no traceback here and the correction still ramps before the I/O stops.

The two processes watch each other, so neither dies unnoticed. The child polls its parent: when the
cycle process dies, it logs that at error level and exits with code 1 (the PLC then sees the service's
heartbeat stop). The parent watches the child through `IoProcess.alive` and `IoProcess.exit_reason`
(`service.app.Service.watch_io`).
"""

from __future__ import annotations

import asyncio
import gc
import logging
import multiprocessing
import os
import signal
import sys
import threading

from io_base.errors import PlcError
from io_base.log_format import configure_logging, current_format
from io_base.scheduling import set_fifo
from plc_link.image import ProcessImage

from .server import IoServer, IoSettings, _serve

log = logging.getLogger("stiffcomp.io")

SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)      # the cycle process's to handle


def ignore_cycle_signals() -> None:
    """A child's first instruction: SIGINT, SIGTERM and SIGHUP are the cycle process's to handle."""
    for s in SIGNALS:
        signal.signal(s, signal.SIG_IGN)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, SIGNALS)


def spawn_child(proc: multiprocessing.Process) -> None:
    """Start a child of the cycle process with SIGINT, SIGTERM and SIGHUP ignored (blocked meanwhile in
    this thread, so one that arrives now is delivered to this process's own handler afterwards, not lost).
    The child calls `ignore_cycle_signals` first; the I/O process and the trace writer start so."""
    if threading.current_thread() is not threading.main_thread():
        proc.start()          # only the main thread may change handlers; the child ignores them itself
        return
    blocked = signal.pthread_sigmask(signal.SIG_BLOCK, SIGNALS)
    handlers = {s: signal.signal(s, signal.SIG_IGN) for s in SIGNALS}
    try:
        proc.start()
    finally:
        for s, h in handlers.items():
            signal.signal(s, h)
        signal.pthread_sigmask(signal.SIG_SETMASK, blocked)


def _main(image: ProcessImage, settings: IoSettings, log_level: int, log_format: str, stop, ready) -> None:
    ignore_cycle_signals()
    configure_logging(log_level, log_format)
    if settings.avoid_cpu is not None:
        try:
            others = os.sched_getaffinity(0) - {settings.avoid_cpu}
            if others:
                os.sched_setaffinity(0, others)
        except (OSError, AttributeError):
            pass
    if settings.robot is not None:          # the robot's clock: its answers before the other protocols' work
        set_fifo(settings.robot.robot.realtime_priority, "I/O process (robot road)", log)
    parent = os.getppid()
    orphaned = []
    image.take_over_inputs()            # a predecessor killed mid-write must not leave its buffer half-locked
    server = IoServer(image, settings)

    class Started:
        def set(self) -> None:
            gc.collect()
            gc.freeze()         # what start-up made is never scanned again: no long collection under the robot's clock
            ready.send("")

    def stop_requested() -> bool:
        if os.getppid() != parent:
            orphaned.append(parent)
        return bool(orphaned) or stop.is_set()

    try:
        asyncio.run(_serve(server, Started(), stop_requested))
    except PlcError as e:
        ready.send(str(e))
    except Exception as e:  # noqa: BLE001 - reported to the parent, which refuses to start
        ready.send(f"the I/O process failed: {e!r}")
    finally:
        image.close()
    try:
        ready.send(server.final_stats)          # the counts, for the service's --stats-json
    except (OSError, ValueError):
        pass
    if orphaned:
        log.error("the cycle process (pid %d) died: the I/O process stops with exit code 1; the PLC sees the "
                  "service's heartbeat stop", parent)
        sys.exit(1)


def describe_exit(exitcode: int | None) -> str:
    """A child's exit code in words: ``killed by SIGKILL``, ``exit code 1``."""
    if exitcode is None:
        return "still running"
    if exitcode < 0:
        try:
            return f"killed by {signal.Signals(-exitcode).name}"
        except ValueError:
            return f"killed by signal {-exitcode}"
    return f"exit code {exitcode}"


class IoProcess:
    """Serve ``image`` with ``settings`` from a child process until `stop`."""

    def __init__(self, image: ProcessImage, settings: IoSettings):
        ctx = multiprocessing.get_context("spawn")
        self.settings = settings
        self._stop = ctx.Event()
        self.final_stats: dict = {}         # what the parts counted, sent by the child as it ends
        self._ready, self._child_end = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_main, args=(image, settings, logging.getLogger().getEffectiveLevel(),
                                                     current_format(), self._stop, self._child_end),
                                 name="stiffcomp-io", daemon=True)

    def start(self, timeout: float = 60.0) -> None:
        spawn_child(self._proc)
        # the child holds its own copy now; closing ours lets a child that dies end the wait at once (EOF)
        self._child_end.close()
        if not self._ready.poll(timeout):
            self.stop()
            raise PlcError(f"the I/O process did not start in {timeout:g} s")
        try:
            msg = self._ready.recv()
        except EOFError:
            self.stop()
            raise PlcError(f"the I/O process died while starting ({describe_exit(self._proc.exitcode)})") from None
        if msg:
            self.stop()
            raise PlcError(msg)

    def stop(self) -> None:
        self._stop.set()
        if self._proc.pid is not None:
            self._proc.join(10.0)
            if self._proc.is_alive():       # it ignores SIGTERM (see the module docstring)
                self._proc.kill()
                self._proc.join(2.0)
        try:
            while self._ready.poll():       # the child's last words: the parts' counts (`IoServer.stats`)
                got = self._ready.recv()
                if isinstance(got, dict):
                    self.final_stats = got
        except (EOFError, OSError):
            pass
        self._ready.close()
        self._child_end.close()

    @property
    def alive(self) -> bool:
        return self._proc.is_alive()

    @property
    def pid(self) -> int | None:
        return self._proc.pid

    @property
    def exit_reason(self) -> str:
        """How the child ended, in words (`describe_exit`)."""
        return describe_exit(self._proc.exitcode)
