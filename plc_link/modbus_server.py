"""The Modbus TCP server role: the PLC polls the service (pymodbus >= 3.16, SimDevice).

pymodbus keeps a register list per table; the device's async ``action`` runs before every request and
makes the image the only truth: a read copies the image's words into pymodbus' list, a write is
checked and applied by `ProcessImage.write` and refused with ILLEGAL_ADDRESS (0x02) before anything
changes. Malformed frames and refused requests are logged rate-limited (`RateLimitedLog`): one line per
client and reason per interval, never a dump per frame (pymodbus' own logger is kept at CRITICAL).

Who may write. Each connection learns once, when it is made, whether its client may write: a plain
client if its address is in ``plc.writers`` (or no list is set), a Modbus/TCP Security client if its
certificate's role allows it (`io_base.tls`). Any other client may use the read functions
(`READ_FUNCTIONS`) only; every other request of it is answered with exception 01 (ILLEGAL_FUNCTION, as
Modbus/TCP Security answers an unauthorized request) before the image is asked, counted, and logged
with the client's address.

Modbus/TCP Security. The same server listens on ``plc.tls.port`` with a `ServerTls`: the TCP connection
is taken into the client table at once and upgraded with the loop's ``start_tls`` (so the handshake's
failure reaches this code: asyncio's own TLS server drops it silently), with a client certificate
required and verified; a refused handshake is logged once per client and reason, and counted.

The server runs on the I/O process's asyncio loop (`io_process.server`); the cycle never waits
for it. Its connections are held by a `ClientTable` (``plc.max_clients``, ``plc.first_frame_timeout_s``,
``plc.idle_timeout_s``), the same policy as the ADS server's: idle clients cannot lock the PLC out.
"""

from __future__ import annotations

import asyncio
import logging

from pymodbus.constants import ExcCodes
from pymodbus.framer import FramerType
from pymodbus.pdu import ExceptionResponse
from pymodbus.server import ModbusTcpServer
from pymodbus.server.requesthandler import ServerRequestHandler
from pymodbus.simulator import DataType, SimData, SimDevice

from io_base.client_table import ClientTable
from io_base.errors import PlcError
from io_base.listen import why_not_listening
from io_base.ratelog import RateLimitedLog
from io_base.settings import ClientLimits

from .image import ProcessImage
from .settings import PlcSettings

log = logging.getLogger("stiffcomp.modbus")

# pymodbus reads the registers back after a write with the write's function code: FC6/16 read too
READ_TABLE = {3: "holding_registers", 4: "input_registers", 6: "holding_registers", 16: "holding_registers",
              23: "holding_registers"}
WRITE_TABLE = {6: "holding_registers", 16: "holding_registers", 23: "holding_registers"}
# what a client that may not write may still ask: the functions that change nothing (FC8, diagnostics,
# is not among them: it can restart the communication or force the server to listen only)
READ_FUNCTIONS = frozenset({1, 2, 3, 4, 7, 11, 12, 17, 20, 24, 43})
NOT_ALLOWED = "write not allowed"


class ModbusServer:
    """Serve ``image`` over Modbus TCP on host:port, or Modbus/TCP Security with ``tls``, on the running loop.

    Parameters
    ----------
    image : ProcessImage
    host, port : where to listen
    on_request : callable (function_code, refused_reason or None) -> None, optional
        Told of every request (metrics).
    limits : `plc_link.settings.PlcSettings` (the ``plc:`` section; its ``writers`` decide which plain
        clients may write) or `ClientLimits` (every client may write), default `ClientLimits()`
    tls : `io_base.tls.ServerTls`, optional
        Serve Modbus/TCP Security: the client certificate's role decides who may write.
    on_connection_refused : callable (reason) -> None, optional
        Told of every connection refused before its first request (metrics).
    """

    def __init__(self, image: ProcessImage, host: str = "127.0.0.1", port: int = 5020, on_request=None,
                 limits: ClientLimits | PlcSettings | None = None, tls=None, on_connection_refused=None):
        self.image = image
        self.host, self.port = host, port
        self.on_request = on_request or (lambda fc, reason: None)
        self.on_connection_refused = on_connection_refused or (lambda reason: None)
        limits = limits or ClientLimits()
        self.may_write = limits.may_write if isinstance(limits, PlcSettings) else (lambda peer: True)
        self.tls = tls
        self.protocol = "modbus_tls" if tls is not None else "modbus"
        self.what = "Modbus/TCP Security" if tls is not None else "Modbus TCP"
        self.errors = RateLimitedLog(log)
        self.table = ClientTable(limits, lambda client, reason: self.errors.report(client.peer, reason))
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

    def refuse_write(self, peer: str, fc: int, why: str) -> None:
        """A client that may not write sent FC ``fc`` (answered with exception 01)."""
        self.errors.report(peer, f"{self.what}: {NOT_ALLOWED} ({why}), exception 01", f"FC{fc}")
        self.on_request(fc, NOT_ALLOWED)

    def refuse_connection(self, peer: str, reason: str, detail: str = "") -> None:
        """A connection closed before its first request (a failed TLS handshake, or the table full)."""
        self.errors.report(peer, f"{self.what}: {reason} (closed)", detail)
        self.on_connection_refused(reason)

    async def start(self) -> None:
        """Bind and serve in the background; PlcError if the address is not available."""
        self._server = _TcpServer(self, self._device(), address=(self.host, self.port))
        key = "plc.tls.port" if self.tls is not None else "plc.port"
        try:
            await self._server.serve_forever(background=True)
        except (OSError, RuntimeError) as e:        # pymodbus: "Could not start listen", the reason swallowed
            raise PlcError(f"cannot serve {self.what} on {self.host}:{self.port}: "
                           f"{why_not_listening(self.host, self.port, key, e)}") from e
        if not self._server.is_active():
            raise PlcError(f"cannot serve {self.what} on {self.host}:{self.port}: "
                           f"{why_not_listening(self.host, self.port, key)}")
        self._sweeper = asyncio.create_task(self._sweep(), name="modbus-clients")
        log.info("%s server on %s:%d", self.what, self.host, self.port)

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
    """pymodbus' TCP server whose connections take their place in the owner's `ClientTable`. Over TLS
    too the frame is Modbus TCP's (MBAP), as Modbus/TCP Security specifies: the socket framer reads
    its length field (pymodbus' TLS framer takes each read as one frame)."""

    def __init__(self, owner: ModbusServer, *args, **kw):
        super().__init__(*args, framer=FramerType.SOCKET, **kw)
        self.owner = owner

    def callback_new_connection(self) -> ServerRequestHandler:
        return _Handler(self, self.trace_packet, self.trace_pdu, self.trace_connect)


class _Handler(ServerRequestHandler):
    """One Modbus client: admitted by the table on connect (over TLS: then upgraded), marked at every
    complete request, removed when it goes (pymodbus calls neither hook when the server closes it; the
    table removes it then). ``may_write`` is decided once, when the connection is made."""

    place = None
    peer = "?"
    may_write = False
    why_not = ""
    _closed_here = False
    _handshake: asyncio.Task | None = None

    def callback_connected(self) -> None:
        super().callback_connected()
        owner: ModbusServer = self.server.owner
        self.peer = str((self.transport.get_extra_info("peername") or ("?",))[0])
        self.place = owner.table.add(self.peer, self.close)
        if self.place is None:
            owner.refuse_connection(self.peer, "max_clients reached, every client polling")
            self.close()
        elif owner.tls is None:
            self.may_write, self.why_not = owner.may_write(self.peer), "address not in plc.writers"
        else:
            self.transport.pause_reading()          # the ClientHello is the TLS layer's to read
            self._handshake = asyncio.create_task(self._start_tls(owner), name="modbus-tls-handshake")

    async def _start_tls(self, owner: ModbusServer) -> None:
        try:
            secure = await self.loop.start_tls(self.transport, self, owner.tls.context(), server_side=True,
                                               ssl_handshake_timeout=owner.table.first_frame_timeout_s)
            if secure is None:                      # the client went away during the handshake
                raise ConnectionResetError("closed during the handshake")
        except OSError as e:                        # ssl.SSLError and TimeoutError among them
            if not self._closed_here:               # not by the table or the server's stop
                from io_base.tls import handshake_failure

                owner.refuse_connection(self.peer, handshake_failure(e), str(getattr(e, "verify_message", "") or e))
            if self.transport is not None:          # pymodbus has not torn it down yet
                self.close()
            owner.table.remove(self.place)
            return
        self.transport = secure
        access, role = owner.tls.access(secure.get_extra_info("ssl_object"))
        self.may_write = access == "write"
        self.why_not = f"certificate role {role!r} may {access}" if role else f"certificate without a role may {access}"
        if access == "none":
            owner.refuse_connection(self.peer, "certificate role without access", self.why_not)
            self.close()

    def close(self, reconnect: bool = False) -> None:
        self._closed_here = True
        super().close(reconnect)

    def callback_data(self, data: bytes, addr: tuple | None = None) -> int:
        used = super().callback_data(data, addr)
        if self.last_pdu is not None and self.place is not None:
            self.server.owner.table.request(self.place)
        return used

    async def handle_request(self):
        """pymodbus' request handling, after the one check of who may write: a request other than a read
        from a client that may not write gets exception 01 and never reaches the image."""
        pdu = self.last_pdu
        if pdu is None or self.may_write or pdu.function_code in READ_FUNCTIONS:
            return await super().handle_request()
        self.server.owner.refuse_write(self.peer, pdu.function_code, self.why_not)
        self.server_send(ExceptionResponse(pdu.function_code, ExcCodes.ILLEGAL_FUNCTION, device_id=pdu.dev_id,
                                           transaction=pdu.transaction_id), self.last_addr)

    def callback_disconnected(self, exc: Exception | None) -> None:
        self.server.owner.table.remove(self.place)
        super().callback_disconnected(exc)
