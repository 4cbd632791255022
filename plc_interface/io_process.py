"""The I/O process: `IoServer` in a process of its own, so the cycle keeps an interpreter to itself.

The child is started with the spawn method (nothing inherited from a threaded parent), is kept off
the cycle's CPU when the cycle is pinned, logs to the parent's stderr in the parent's format, and
stops when the parent sets its stop event (or dies: the child polls its parent).
"""

from __future__ import annotations

import asyncio
import logging
import multiprocessing
import os

from .errors import PlcError
from .image import ProcessImage
from .io_server import IoServer, IoSettings, _serve
from .log_format import configure_logging, current_format


def _main(image: ProcessImage, settings: IoSettings, log_level: int, log_format: str, stop, ready) -> None:
    configure_logging(log_level, log_format)
    if settings.avoid_cpu is not None:
        try:
            others = os.sched_getaffinity(0) - {settings.avoid_cpu}
            if others:
                os.sched_setaffinity(0, others)
        except (OSError, AttributeError):
            pass
    parent = os.getppid()
    server = IoServer(image, settings)

    class Started:
        def set(self) -> None:
            ready.send("")

    try:
        asyncio.run(_serve(server, Started(), lambda: stop.is_set() or os.getppid() != parent))
    except PlcError as e:
        ready.send(str(e))
    except Exception as e:  # noqa: BLE001 - reported to the parent, which refuses to start
        ready.send(f"the I/O process failed: {e!r}")
    finally:
        image.close()


class IoProcess:
    """Serve ``image`` with ``settings`` from a child process until `stop`."""

    def __init__(self, image: ProcessImage, settings: IoSettings):
        ctx = multiprocessing.get_context("spawn")
        self.settings = settings
        self._stop = ctx.Event()
        self._ready, self._child_end = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_main, args=(image, settings, logging.getLogger().getEffectiveLevel(),
                                                     current_format(), self._stop, self._child_end),
                                 name="stiffcomp-io", daemon=True)

    def start(self, timeout: float = 60.0) -> None:
        self._proc.start()
        # the child holds its own copy now; closing ours lets a child that dies end the wait at once (EOF)
        self._child_end.close()
        if not self._ready.poll(timeout):
            self.stop()
            raise PlcError(f"the I/O process did not start in {timeout:g} s")
        try:
            msg = self._ready.recv()
        except EOFError:
            self.stop()
            raise PlcError(f"the I/O process died while starting (exit code {self._proc.exitcode})") from None
        if msg:
            self.stop()
            raise PlcError(msg)

    def stop(self) -> None:
        self._stop.set()
        if self._proc.pid is not None:
            self._proc.join(10.0)
            if self._proc.is_alive():
                self._proc.terminate()
                self._proc.join(2.0)
        self._ready.close()
        self._child_end.close()

    @property
    def alive(self) -> bool:
        return self._proc.is_alive()
