"""The Modbus TCP server role: the PLC polls the service (pymodbus >= 3.16, SimDevice).

pymodbus keeps a register list per table; the device's async ``action`` runs before every request and
makes the image the only truth: a read copies the image's words into pymodbus' list, a write is
checked and applied by `ProcessImage.write` and refused with ILLEGAL_ADDRESS (0x02) before anything
changes. Malformed frames and refused requests are logged rate-limited (`RateLimitedLog`): one line per
client and reason per interval, never a dump per frame (pymodbus' own logger is kept at CRITICAL).

The server runs on the I/O process's asyncio loop (`plc_interface.io_server`); the cycle never waits
for it. Its connections are held by a `ClientTable` (``plc.max_clients``, ``plc.first_frame_timeout_s``,
``plc.idle_timeout_s``), the same policy as the ADS server's: idle clients cannot lock the PLC out.
"""

from __future__ import annotations

import asyncio
import logging

from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler
from pymodbus.simulator import DataType, SimData, SimDevice

from .client_table import ClientTable
from .errors import PlcError
from .image import ProcessImage
from .ratelog import RateLimitedLog
from .settings import ClientLimits

log = logging.getLogger("stiffcomp.modbus")

# pymodbus reads the registers back after a write with the write's function code: FC6/16 read too
READ_TABLE = {3: "holding_registers", 4: "input_registers", 6: "holding_registers", 16: "holding_registers",
              23: "holding_registers"}
WRITE_TABLE = {6: "holding_registers", 16: "holding_registers", 23: "holding_registers"}


class ModbusServer:
    """Serve ``image`` over Modbus TCP on host:port, on the running asyncio loop.

    Parameters
    ----------
    image : ProcessImage
    host, port : where to listen
    on_request : callable (function_code, refused_reason or None) -> None, optional
        Told of every request (metrics).
    limits : `plc_interface.settings.ClientLimits` (the ``plc:`` section), default its defaults
    """

    protocol = "modbus"

    def __init__(self, image: ProcessImage, host: str = "127.0.0.1", port: int = 5020, on_request=None,
                 limits: ClientLimits | None = None):
        self.image = image
        self.host, self.port = host, port
        self.on_request = on_request or (lambda fc, reason: None)
        self.errors = RateLimitedLog(log)
        self.table = ClientTable(limits or ClientLimits(),
                                   lambda client, reason: self.errors.report(client.peer, reason))
        self._server: ModbusTcpServer | None = None
        self._sweeper: asyncio.Task | None = None
        logging.getLogger("pymodbus").setLevel(logging.CRITICAL)     # no hex dump per bad frame

    def _device(self) -> SimDevice:
        """One shared register list over the whole address space, so that every request, whatever its
        table, reaches the action and the image decides (and counts) what is refused. The action knows
        the table from the function code; coils and discrete inputs (FC1, FC2, FC5, FC15) are refused
        with ILLEGAL_FUNCTION."""
        return SimDevice(0, simdata=[SimData(0, count=0x10000, values=0, datatype=DataType.REGISTERS)],
                         action=self._action)

    async def _action(self, function_code: int, start_address: int, address: int, count: int,
                      registers: list[int], set_values) -> ExcCodes | None:
        if set_values is not None and function_code in WRITE_TABLE:
            if not self.image.write(WRITE_TABLE[function_code], address, list(set_values)):
                return self._refuse(function_code, "write outside the PLC's registers", address, count)
            self.on_request(function_code, None)
            return None
        table = READ_TABLE.get(function_code)
        if table is None:
            return self._refuse(function_code, "unsupported function", address, count, ExcCodes.ILLEGAL_FUNCTION)
        words = self.image.read(table, address, count)
        if words is None:
            return self._refuse(function_code, "read outside the map's blocks", address, count)
        registers[address - start_address: address - start_address + count] = words
        self.on_request(function_code, None)
        return None

    def _refuse(self, fc: int, reason: str, address: int, count: int,
                code: ExcCodes = ExcCodes.ILLEGAL_ADDRESS) -> ExcCodes:
        self.errors.report("modbus", reason, f"FC{fc} at {address:#06x}+{count}")
        self.on_request(fc, reason)
        return code

    async def start(self) -> None:
        """Bind and serve in the background; PlcError if the address is not available."""
        self._server = _TcpServer(self.table, self.errors, self._device(), address=(self.host, self.port))
        try:
            await self._server.serve_forever(background=True)
        except (OSError, RuntimeError) as e:
            raise PlcError(f"cannot serve Modbus TCP on {self.host}:{self.port}: {e}") from e
        if not self._server.is_active():
            raise PlcError(f"cannot serve Modbus TCP on {self.host}:{self.port}: address not available")
        self._sweeper = asyncio.create_task(self._sweep(), name="modbus-clients")
        log.info("Modbus TCP server on %s:%d", self.host, self.port)

    async def _sweep(self) -> None:
        while True:
            await asyncio.sleep(self.table.sweep_interval_s)
            self.table.sweep()

    async def stop(self) -> None:
        if self._sweeper is not None:
            self._sweeper.cancel()
            await asyncio.gather(self._sweeper, return_exceptions=True)
            self._sweeper = None
        if self._server is not None:
            await self._server.shutdown()
            self._server = None

    @property
    def clients(self) -> int:
        """Connected clients (for metrics)."""
        s = self._server
        return len(getattr(s, "active_connections", {}) or {}) if s is not None else 0


class _TcpServer(ModbusTcpServer):
    """pymodbus' TCP server whose connections take their place in a `ClientTable`."""

    def __init__(self, table: ClientTable, errors: RateLimitedLog, *args, **kw):
        super().__init__(*args, **kw)
        self.table, self.errors = table, errors

    def callback_new_connection(self) -> ServerRequestHandler:
        return _Handler(self, self.trace_packet, self.trace_pdu, self.trace_connect)


class _Handler(ServerRequestHandler):
    """One Modbus client: admitted by the table on connect, marked at every complete request, removed
    when it goes (pymodbus calls neither hook when the server closes it; the table removes it then)."""

    place = None

    def callback_connected(self) -> None:
        super().callback_connected()
        peer = str((self.transport.get_extra_info("peername") or ("?",))[0])
        self.place = self.server.table.add(peer, self.close)
        if self.place is None:
            self.server.errors.report(peer, "max_clients reached, every client polling (closed)")
            self.close()

    def callback_data(self, data: bytes, addr: tuple | None = None) -> int:
        used = super().callback_data(data, addr)
        if self.last_pdu is not None and self.place is not None:
            self.server.table.request(self.place)
        return used

    def callback_disconnected(self, exc: Exception | None) -> None:
        self.server.table.remove(self.place)
        super().callback_disconnected(exc)
