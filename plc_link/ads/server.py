"""The ADS server: AMS/TCP on asyncio, mounted on the I/O process's loop beside Modbus.

The server meets the cycle only through an `ImagePort`: it reads `snapshot()` and writes PLC registers
with `write()`; the cycle never waits on it. Notifications learn of a new cycle by polling the
snapshot's version every ``notify_poll_s`` (1 ms) from the server's own task, only while some client
has a notification; `on_cycle` does the same at once for an I/O process that knows when a cycle was
published. Both send each cycle's samples once.

The same AMS Net ID answers on AMS port 10000 as TwinCAT's system service does (`system_command`):
its state (RUN while the server serves), its device info, and no writes; ads-client reads that state
before it talks to the PLC runtime and every second after.

Before its first request a client may ask the server, as its AMS router, for an AMS address (port
connect, `router`); the port lent to it is given back by port close, which ends the connection, or
when the connection ends otherwise.

Malformed input (docs/ads.md): a frame with a usable AMS header gets an error reply (wrong length,
target or command); one without (short header, an AMS/TCP command other than an AMS frame, port connect
or port close, announced length over the limit), a malformed port connect or close, a response sent to
the server, or a request from an unknown route closes the connection.
Every other client is served on. Errors are logged rate-limited (`RateLimitedLog`).
"""

from __future__ import annotations

import asyncio
import itertools
import logging

from io_base.client_table import ClientTable
from io_base.ratelog import RateLimitedLog

from . import ams, router
from .area import AreaView
from .notifications import Notifications
from .port import ImagePort
from .session import Device, Session
from .settings import AdsSettings

log = logging.getLogger("stiffcomp.ads")
VERSION = (0, 1, 0)       # ReadDeviceInfo: major, minor, build


class Closing(Exception):
    """The connection is to be closed; ``reason`` is logged (rate-limited by it), ``detail`` with it."""

    def __init__(self, reason: str, detail: str = ""):
        super().__init__(reason)
        self.reason, self.detail = reason, detail


class Connection:
    """One client's TCP connection: its session (handles) and its notifications."""

    def __init__(self, server: AdsServer, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, peer: str):
        self.server, self.reader, self.writer, self.peer = server, reader, writer, peer
        self.session = Session(server.device)
        self.notes = Notifications(self.session, server.settings.max_notifications, server.note_ids)
        self.place = None               # its place in the server's ClientTable
        self.ams_port: int | None = None    # the AMS port lent to it by port connect, if it asked

    async def serve(self) -> None:
        try:
            while True:
                frame = await self._next_frame()
                if frame is None:
                    return
                command, body = frame
                self.server.table.request(self.place)
                if command == router.AMS_FRAME:
                    reply = self.server.answer(self, body)
                else:
                    reply = self._router_command(command, body)
                    if reply is None:
                        return
                self.writer.write(reply)
                await self.writer.drain()
        except Closing as e:
            self.server.ratelog.report(self.peer, e.reason, e.detail)
        except (ConnectionError, asyncio.IncompleteReadError):
            pass

    async def _next_frame(self) -> tuple[int, bytes] | None:
        """(AMS/TCP command, the bytes after the AMS/TCP header) of the next frame; None at the end."""
        try:
            head = await self.reader.readexactly(ams.TCP_HEADER_SIZE)
        except asyncio.IncompleteReadError:
            return None             # closed by the client between frames: the normal end
        command, length = ams.TCP_HEADER.unpack(head)
        if command in router.ROUTER_COMMANDS:
            if length != router.PORT_REQ.size:
                raise Closing("AMS/TCP port connect or close not of 2 bytes (closed)", f"length {length}")
        elif command != router.AMS_FRAME:
            raise Closing("AMS/TCP command that is no AMS frame, port connect or port close (closed)",
                          f"command {command:#06x}")
        elif length < ams.AMS_HEADER_SIZE:
            raise Closing("AMS frame shorter than its 32-byte header (closed)")
        elif length > self.server.settings.max_frame_bytes:
            raise Closing("AMS frame longer than max_frame_bytes (closed)")
        try:        # a frame begun must end: a client stalled mid-frame must not hold its slot for ever
            body = await asyncio.wait_for(self.reader.readexactly(length), self.server.settings.frame_timeout_s)
        except TimeoutError:
            raise Closing("frame not completed within frame_timeout_s (closed)") from None
        return command, body

    def _router_command(self, command: int, body: bytes) -> bytes | None:
        """The reply to a port connect (the client's AMS address); None after a port close (the end)."""
        (port,) = router.PORT_REQ.unpack(body)
        name = router.ROUTER_COMMANDS[command]
        if command == router.PORT_CONNECT:
            if self.ams_port is None:       # one port per connection: asked again, the same answer
                self.ams_port = self.server.ports.lend(port)
            self.server.on_request(name, None)
            net_id = ams.net_id_bytes(self.server.settings.client_net_id(self.peer))
            return router.port_connect_reply(net_id, self.ams_port)
        if port != self.ams_port:
            self.server.on_request(name, "port_not_held")
            raise Closing("port close for a port this connection does not hold (closed)", f"port {port}")
        self.server.on_request(name, None)
        return None

    def send_due(self, view: AreaView) -> None:
        """Queue this cycle's notification frames, unless the client has stopped reading."""
        frames = self.notes.due(view, self.server.net_id, self.server.settings.ams_port)
        if not frames or self.writer.is_closing():
            return
        if self.writer.transport.get_write_buffer_size() > self.server.settings.max_send_buffer:
            self.server.ratelog.report(self.peer, "client not reading: notifications skipped")
            return
        for f in frames:
            self.writer.write(f)


class AdsServer:
    """An ADS device over the process image, at ``settings.host:settings.port``.

    Parameters
    ----------
    port : ImagePort, the process image
    settings : AdsSettings
    logger : where protocol errors go (rate-limited), default ``stiffcomp.ads``
    on_request : callable (command name, refused reason or None) -> None, optional
        Told of every request that reached the server (the metrics count them by command).
    """

    def __init__(self, port: ImagePort, settings: AdsSettings, logger: logging.Logger | None = None,
                 on_request=None):
        self.port, self.settings = port, settings
        self.on_request = on_request or (lambda command, reason: None)
        self.net_id = ams.net_id_bytes(settings.net_id)
        self.device = Device(port, settings.max_handles, settings.max_sum_requests, settings.max_frame_bytes)
        self.ratelog = RateLimitedLog(logger or log, settings.log_interval_s)
        self.note_ids = itertools.count(1)
        self.connections: set[Connection] = set()
        self.ports = router.PortTable({settings.ams_port, ams.SYSTEM_SERVICE_PORT})
        self.table = ClientTable(settings, lambda client, reason: self.ratelog.report(client.peer, reason))
        self._server: asyncio.Server | None = None
        self._poller: asyncio.Task | None = None
        self._sweeper: asyncio.Task | None = None
        self._tasks: set[asyncio.Task] = set()
        self._wake = asyncio.Event()
        self._version: int | None = None
        self._tracebacks: set[type] = set()

    # -- life cycle --------------------------------------------------------------------------------
    async def start(self) -> None:
        """Bind and serve on the running loop (raises OSError if the address is taken)."""
        self._wake = asyncio.Event()
        self._server = await asyncio.start_server(self._accept, self.settings.host, self.settings.port)
        self._poller = asyncio.create_task(self._poll(), name="ads-notify")
        self._sweeper = asyncio.create_task(self._sweep(), name="ads-clients")

    @property
    def address(self) -> tuple[str, int]:
        """The bound (host, port); the port is the one chosen when the settings say 0."""
        return self._server.sockets[0].getsockname()[:2]

    async def stop(self) -> None:
        """Close the listener and every connection; wait for their tasks."""
        if self._server is not None:
            self._server.close()
        for task in (self._poller, self._sweeper):
            if task is not None:
                task.cancel()
        for conn in list(self.connections):
            conn.writer.transport.abort()       # not close(): a client that does not read would hold it open
        tasks = [t for t in (*self._tasks, self._poller, self._sweeper) if t is not None]
        await asyncio.gather(*tasks, return_exceptions=True)
        if self._server is not None:
            await self._server.wait_closed()
        self._server = self._poller = self._sweeper = None
        self.ratelog.flush()

    # -- notifications -----------------------------------------------------------------------------
    def on_cycle(self) -> None:
        """Send the notifications due for the newest published cycle (once per cycle; cheap if none)."""
        if not any(c.notes.items for c in self.connections):
            return
        snap = self.port.snapshot()
        if snap[0] in (self._version, 0):       # the same cycle again, or none published yet
            return
        self._version = snap[0]
        view = self.device.view_of(snap)
        for conn in list(self.connections):
            conn.send_due(view)

    async def _poll(self) -> None:
        while True:
            if not any(c.notes.items for c in self.connections):
                self._wake.clear()
                await self._wake.wait()
            try:
                self.on_cycle()
            except Exception as e:  # noqa: BLE001 (the image gone, or a bug: keep serving requests)
                self._bug(e, "sampling notifications failed")
            await asyncio.sleep(self.settings.notify_poll_s)

    # -- connections -------------------------------------------------------------------------------
    async def _sweep(self) -> None:
        while True:
            await asyncio.sleep(self.table.sweep_interval_s)
            self.table.sweep()

    async def _accept(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        self._tasks.add(task)
        peer = str((writer.get_extra_info("peername") or ("?",))[0])
        conn = None
        try:
            if not self.settings.allows(peer):
                self.ratelog.report(peer, "no route for this address (closed)")
                return
            conn = Connection(self, reader, writer, peer)
            conn.place = self.table.add(peer, writer.transport.abort, lambda: bool(conn.notes.items))
            if conn.place is None:
                self.ratelog.report(peer, "max_clients reached, every client polling (closed)")
                return
            self.connections.add(conn)
            await conn.serve()
        finally:
            if conn is not None:
                self.table.remove(conn.place)
                self.ports.give_back(conn.ams_port)
            self.connections.discard(conn)
            writer.close()
            try:
                await writer.wait_closed()
            except (ConnectionError, OSError):
                pass
            self._tasks.discard(task)

    def answer(self, conn: Connection, frame: bytes) -> bytes:
        """The reply frame to one AMS frame; raises Closing where no reply can be given."""
        h = ams.AmsHeader.parse(frame)
        name = ams.COMMAND_NAMES.get(h.command, "unknown")
        if h.flags & ams.FLAG_RESPONSE:
            self.on_request(name, "response_frame")
            raise Closing("a response frame sent to the server (closed)")
        if not self.settings.allows(conn.peer, ams.net_id_text(h.source)):
            self.on_request(name, "no_route")
            raise Closing("no route for this AMS Net ID (closed)", f"Net ID {ams.net_id_text(h.source)}")
        error = 0
        if h.length != len(frame) - ams.AMS_HEADER_SIZE:
            error, reason = ams.ERR_INVALID_AMS_LENGTH, "AMS length disagrees with the frame"
        elif h.target != self.net_id:
            error, reason = ams.ERR_TARGET_MACHINE_NOT_FOUND, "wrong target AMS Net ID"
        elif h.target_port not in (self.settings.ams_port, ams.SYSTEM_SERVICE_PORT):
            error, reason = ams.ERR_TARGET_PORT_NOT_FOUND, "wrong target AMS port"
        elif h.command not in ams.COMMANDS:
            error, reason = ams.ADSERR_SRV_NOT_SUPP, "unknown ADS command"
        if error:
            self.ratelog.report(conn.peer, reason)
            self.on_request(name, f"ads_error_{error:#x}")
            return h.reply(b"", error)
        try:
            payload = (self.system_command if h.target_port == ams.SYSTEM_SERVICE_PORT else self.command)(
                conn, h, frame[ams.AMS_HEADER_SIZE:])
        except Exception as e:  # noqa: BLE001 (a bug must cost one request, not the server)
            self._bug(e, f"ADS request {h.command:#x} from {conn.peer} failed", conn.peer)
            self.on_request(name, "internal_error")
            return h.reply(b"", ams.ADSERR_DEVICE_ERROR)
        result = int.from_bytes(payload[:4], "little") if len(payload) >= 4 else 0
        self.on_request(name, f"ads_error_{result:#x}" if result else None)
        return h.reply(payload)

    def _bug(self, e: Exception, what: str, client: str = "server") -> None:
        """Log an unexpected exception: its traceback once per kind, then rate-limited counts."""
        if type(e) not in self._tracebacks:
            self._tracebacks.add(type(e))
            log.error("%s", what, exc_info=e)
        self.ratelog.report(client, f"internal error: {type(e).__name__}")

    def _device_info(self) -> bytes:
        return ams.DEVICE_INFO_RES.pack(0, *VERSION, self.settings.device_name.encode("latin-1", "replace"))

    def system_command(self, conn: Connection, h: ams.AmsHeader, payload: bytes) -> bytes:
        """The response payload of a request to the system service (AMS port 10000)."""
        cmd = h.command
        if cmd == ams.READ_DEVICE_INFO:
            return self._device_info()
        if cmd == ams.READ_STATE:                  # the system runs while it answers; the PLC's state is 0xF100
            return ams.STATE_RES.pack(0, ams.ADSSTATE_RUN, 0)
        if cmd == ams.WRITE_CONTROL:                # no client switches the service to config mode or restarts it
            return ams.result_response(ams.ADSERR_SRV_NOT_SUPP)
        if cmd == ams.DEL_NOTIFICATION:
            return ams.result_response(ams.ADSERR_NOTIFY_HANDLE_INVALID)
        if cmd == ams.ADD_NOTIFICATION:
            return ams.ADD_NOTE_RES.pack(ams.ADSERR_INVALID_GROUP, 0)
        if cmd == ams.WRITE:
            return ams.result_response(ams.ADSERR_INVALID_GROUP)
        return ams.read_response(ams.ADSERR_INVALID_GROUP)      # Read, ReadWrite: it serves no index group

    def command(self, conn: Connection, h: ams.AmsHeader, payload: bytes) -> bytes:
        """The response payload of one well-addressed request to the PLC runtime (``ams_port``)."""
        s, cmd = conn.session, h.command
        if cmd == ams.READ_DEVICE_INFO:
            return self._device_info()
        if cmd == ams.READ_STATE:
            return ams.STATE_RES.pack(0, self.device.view().ads_state, 0)
        if cmd == ams.WRITE_CONTROL:
            return ams.result_response(ams.ADSERR_SRV_NOT_SUPP)    # the service's state is not the client's
        if cmd == ams.DEL_NOTIFICATION:
            return conn.notes.delete(payload)
        if cmd == ams.ADD_NOTIFICATION:
            out = conn.notes.add(h, payload, self.device.view())
            self._wake.set()
            return out
        if cmd == ams.READ:
            if len(payload) != ams.READ_REQ.size:
                return ams.read_response(self._bad(conn, "Read of wrong size"))
            return ams.read_response(*s.read(self.device.view(), *ams.READ_REQ.unpack(payload)))
        if cmd == ams.WRITE:
            if len(payload) < ams.WRITE_REQ.size:
                return ams.result_response(self._bad(conn, "Write of wrong size"))
            group, offset, length = ams.WRITE_REQ.unpack_from(payload)
            data = payload[ams.WRITE_REQ.size:]
            if length != len(data):
                return ams.result_response(self._bad(conn, "Write length disagrees with its data"))
            return ams.result_response(s.write(group, offset, data))
        # READ_WRITE (the commands are checked in `answer`)
        if len(payload) < ams.READ_WRITE_REQ.size:
            return ams.read_response(self._bad(conn, "ReadWrite of wrong size"))
        group, offset, rlen, wlen = ams.READ_WRITE_REQ.unpack_from(payload)
        data = payload[ams.READ_WRITE_REQ.size:]
        if wlen != len(data):
            return ams.read_response(self._bad(conn, "ReadWrite length disagrees with its data"))
        return ams.read_response(*s.read_write(self.device.view(), group, offset, rlen, data))

    def _bad(self, conn: Connection, reason: str) -> int:
        self.ratelog.report(conn.peer, reason)
        return ams.ADSERR_INVALID_SIZE
