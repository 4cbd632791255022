"""The Modbus TCP server role in a process of its own, serving a `SharedRegisterImage`.

Same behaviour as `ModbusServerThread` (it runs one inside the child); the cycle keeps its own
interpreter lock. The child is started with the spawn method (no state inherited from a threaded
parent) and is kept off the cycle's CPU when the cycle is pinned.
"""

from __future__ import annotations

import multiprocessing
import os

from .errors import PlcError
from .shared_image import SharedRegisterImage


def _serve(image: SharedRegisterImage, host: str, port: int, avoid_cpu: int | None, stop, ready) -> None:
    from .modbus_server import ModbusServerThread

    if avoid_cpu is not None:
        try:
            others = os.sched_getaffinity(0) - {avoid_cpu}
            if others:
                os.sched_setaffinity(0, others)
        except (OSError, AttributeError):
            pass
    server = ModbusServerThread(image, host, port)
    try:
        server.start()
    except PlcError as e:
        ready.send(str(e))
        return
    ready.send("")
    try:
        stop.wait()
    finally:
        server.stop()
        image.close()


class ModbusServerProcess:
    """Serve ``image`` on host:port from a child process until `stop`."""

    def __init__(self, image: SharedRegisterImage, host: str = "127.0.0.1", port: int = 5020,
                 avoid_cpu: int | None = None):
        ctx = multiprocessing.get_context("spawn")
        self.host, self.port = host, port
        self._stop = ctx.Event()
        self._ready, self._child_end = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_serve, args=(image, host, port, avoid_cpu, self._stop, self._child_end),
                                 name="stiffcomp-modbus", daemon=True)

    def start(self, timeout: float = 30.0) -> None:
        self._proc.start()
        # the child holds its own copy now; closing ours lets a child that dies end the wait at once (EOF)
        self._child_end.close()
        if not self._ready.poll(timeout):
            self.stop()
            raise PlcError(f"the Modbus server process did not start on {self.host}:{self.port} in {timeout:g} s")
        try:
            msg = self._ready.recv()
        except EOFError:
            self.stop()
            raise PlcError(f"the Modbus server process for {self.host}:{self.port} died while starting "
                           f"(exit code {self._proc.exitcode})") from None
        if msg:
            self.stop()
            raise PlcError(msg)

    def stop(self) -> None:
        self._stop.set()
        self._proc.join(5.0)
        if self._proc.is_alive():
            self._proc.terminate()
            self._proc.join(2.0)
        self._ready.close()
        self._child_end.close()

    @property
    def alive(self) -> bool:
        return self._proc.is_alive()
