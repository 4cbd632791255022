"""The Modbus TCP server role: the PLC polls the service (pymodbus, classic datastore).

pymodbus 3.9-3.12 is pinned on purpose: its classic datastore lets a device context answer each
request with an exception code, which is how writes outside the PLC's registers are refused with
ILLEGAL_ADDRESS (0x02) before anything changes. pymodbus 3.13 replaced that datastore with
SimDevice/SimData and an async action callback; porting is possible but buys nothing here.

The server runs its own asyncio loop in a thread; the cycle thread never waits for it. The only
shared state is the `RegisterImage` and its lock.
"""

from __future__ import annotations

import asyncio
import logging
import threading

from pymodbus.constants import ExcCodes
from pymodbus.datastore import ModbusServerContext
from pymodbus.datastore.context import ModbusBaseDeviceContext
from pymodbus.server import ModbusTcpServer

from .errors import PlcError
from .image import FC_TABLE, RegisterImage

log = logging.getLogger("stiffcomp.modbus")


class ImageDeviceContext(ModbusBaseDeviceContext):
    """A pymodbus device context backed by the register image (addresses are 0-based Modbus addresses)."""

    def __init__(self, image: RegisterImage):
        self.image = image

    def reset(self) -> None:
        """Registers are owned by the service; a Modbus reset changes nothing."""

    def getValues(self, func_code, address, count=1):
        table = FC_TABLE.get(func_code)
        if table is None:
            return ExcCodes.ILLEGAL_FUNCTION
        words = self.image.read(table, address, count)
        return ExcCodes.ILLEGAL_ADDRESS if words is None else words

    def setValues(self, func_code, address, values):
        table = FC_TABLE.get(func_code)
        if table is None or not isinstance(values, list) or not values or isinstance(values[0], bool):
            return ExcCodes.ILLEGAL_FUNCTION
        if not self.image.write(table, address, values):
            log.warning("refused a write of %d register(s) at %#06x: not a PLC register", len(values), address)
            return ExcCodes.ILLEGAL_ADDRESS
        return None


class ModbusServerThread:
    """Serve ``image`` on host:port until `stop`.

    Parameters
    ----------
    image : RegisterImage or None
    host, port : where to listen
    context : ModbusServerContext, optional
        Serve this context instead of the image (a plain PLC memory for tests and the virtual PLC).
    """

    def __init__(self, image: RegisterImage | None, host: str = "127.0.0.1", port: int = 5020,
                 context: ModbusServerContext | None = None):
        self.image = image
        self.context = context
        self.host, self.port = host, port
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: ModbusTcpServer | None = None
        self._thread = threading.Thread(target=self._run, name="stiffcomp-modbus", daemon=True)
        self._ready = threading.Event()
        self._error: BaseException | None = None

    def start(self, timeout: float = 5.0) -> None:
        self._thread.start()
        if not self._ready.wait(timeout) or self._error is not None:
            self.stop()
            raise PlcError(f"cannot serve Modbus TCP on {self.host}:{self.port}: {self._error}") from self._error

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        asyncio.set_event_loop(loop)
        try:
            loop.run_until_complete(self._serve())
        except BaseException as e:  # noqa: BLE001 - reported to start()
            self._error = e
            self._ready.set()
        finally:
            loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    async def _serve(self) -> None:
        context = self.context or ModbusServerContext(devices=ImageDeviceContext(self.image), single=True)
        self._server = ModbusTcpServer(context, address=(self.host, self.port))
        await self._server.serve_forever(background=True)
        if not self._server.is_active():
            raise OSError(f"address {self.host}:{self.port} not available")
        log.info("Modbus TCP server on %s:%d", self.host, self.port)
        self._ready.set()
        self._stopped = asyncio.Event()
        await self._stopped.wait()
        await self._server.shutdown()

    def stop(self) -> None:
        loop = self._loop
        if loop is not None and self._thread.is_alive() and hasattr(self, "_stopped"):
            loop.call_soon_threadsafe(self._stopped.set)
        if self._thread.is_alive():
            self._thread.join(5.0)
