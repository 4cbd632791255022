"""The I/O side of the service: one asyncio loop serving every protocol from the process image.

`IoServer` mounts, on one loop, the Modbus TCP server (or the Modbus client role, which writes into a
PLC's TF6250 registers), the robot road, the ADS server and the monitoring endpoint: a server on each
address its settings declare (`IoSettings.listeners`, which `stiffcomp run --check` checks before a
start). It meets the cycle only in the `ProcessImage`. In production it runs in a process of its own
(`IoProcess`, the only layout `stiffcomp run` uses); `IoThread` runs the very same `IoServer` on a loop in
a thread of the caller, for tests of the protocols without a service.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from dataclasses import dataclass, field
from typing import Any

from io_base.errors import PlcError
from io_base.listen import Listener
from plc_link.image import ProcessImage
from plc_link.settings import PlcSettings

log = logging.getLogger("stiffcomp.io")


@dataclass
class IoSettings:
    """What the I/O process serves: the PLC role, and the optional ADS, monitoring and robot road sections."""

    plc: PlcSettings = field(default_factory=PlcSettings)
    ads: Any = None                 # plc_link.ads.AdsSettings, or None (no ADS server)
    monitoring: Any = None          # io_process.settings.MonitoringSettings, or None
    robot: Any = None               # robot_road.road.RoadSettings, or None (no robot road)
    avoid_cpu: int | None = None    # keep the I/O process off the cycle's CPU when it is pinned

    def listeners(self) -> list[Listener]:
        """Every address the I/O process listens on, in the order `IoServer.start` starts a server on each:
        plain Modbus TCP (``plc.role: server``, unless TLS alone), Modbus/TCP Security, the robot road (its
        own settings' address, UDP), ADS, monitoring. `stiffcomp run --check` checks these
        (`service.preflight`). The Modbus client role listens on nothing."""
        plc, out = self.plc, []
        if plc.role == "server":
            if not plc.tls.enabled or plc.tls.plain:
                out.append(Listener("plc.port", plc.host, plc.port))
            if plc.tls.enabled:
                out.append(Listener("plc.tls.port", plc.host, plc.tls.port))
        if self.robot is not None and self.robot.robot.enabled:
            road = self.robot.robot
            out.append(Listener("robot.port", road.host, road.port, "udp"))
        for key, section in (("ads.port", self.ads), ("monitoring.port", self.monitoring)):
            if section is not None and section.enabled:
                out.append(Listener(key, section.host, section.port))
        return out


class IoServer:
    """Every protocol of the service on the running asyncio loop.

    Parameters
    ----------
    image : ProcessImage
    settings : IoSettings
    """

    def __init__(self, image: ProcessImage, settings: IoSettings):
        self.image = image
        self.settings = settings
        self.parts: list[Any] = []
        self.final_stats: dict = {}
        self.metrics = None
        if settings.monitoring is not None and settings.monitoring.metrics:
            from .metrics import ServiceMetrics

            self.metrics = ServiceMetrics()      # fault kinds from the contract

    async def start(self) -> None:
        """Start the Modbus client (``plc.role: client``), then a server on each of the settings' listeners
        (`IoSettings.listeners`), in their order; on failure the parts already started are stopped and
        PlcError is raised."""
        servers = {"plc.port": self._modbus, "plc.tls.port": self._modbus_tls, "robot.port": self._road,
                   "ads.port": self._ads, "monitoring.port": self._monitor}
        try:
            if self.settings.plc.role == "client":
                await self._add(self._modbus_client())
            for listener in self.settings.listeners():
                await self._add(servers[listener.key](listener))
        except BaseException:
            await self.stop()
            raise

    def _modbus_client(self):
        """The Modbus client role: writes into a PLC's TF6250 registers and reads its inputs."""
        from plc_link.modbus_client import ModbusClient

        plc = self.settings.plc
        c = plc.client
        return ModbusClient(self.image, plc.host, plc.port, plc.device_id, c.period_ms / 1000.0, c.timeout_s,
                            c.write_start, c.read_table, c.read_start)

    def _modbus(self, at: Listener):
        """Plain Modbus TCP on ``plc.port``."""
        from plc_link.modbus_server import ModbusServer

        plc = self.settings.plc
        warning = plc.exposure_warning()
        if warning:
            log.warning(warning)
        return ModbusServer(self.image, at.host, at.port, self._count_modbus, limits=plc,
                            on_connection_refused=self._count_connection("modbus"))

    def _modbus_tls(self, at: Listener):
        """Modbus/TCP Security on ``plc.tls.port``."""
        from io_base.tls import ServerTls
        from plc_link.modbus_server import ModbusServer

        plc = self.settings.plc
        return ModbusServer(self.image, at.host, at.port, self._count_modbus_tls, limits=plc,
                            tls=ServerTls(plc.tls), on_connection_refused=self._count_connection("modbus_tls"))

    def _road(self, at: Listener):
        """The robot road; it binds the address of its own settings, which ``at`` was read from."""
        from robot_road.road import RobotRoad

        return RobotRoad(self.image, self.settings.robot, self.metrics)

    def _ads(self, at: Listener):
        """The ADS server; it binds the address of its settings, which ``at`` was read from."""
        return _Ads(self.image, self.settings.ads, self._count_ads)

    def _monitor(self, at: Listener):
        """The HTTP endpoint (health, metrics); it binds the address of its settings, which ``at`` was read
        from."""
        from .monitoring import Monitor

        return Monitor(self.image, self.settings.monitoring, self.metrics, parts=lambda: self.parts)

    def _count_modbus(self, function_code: int, refused: str | None) -> None:
        """Every Modbus request, for the metrics: by function, and refused ones by reason."""
        self._count("modbus", f"FC{function_code}", refused)

    def _count_modbus_tls(self, function_code: int, refused: str | None) -> None:
        """Every Modbus/TCP Security request, as `_count_modbus`."""
        self._count("modbus_tls", f"FC{function_code}", refused)

    def _count_connection(self, protocol: str):
        """The counter of connections of ``protocol`` refused before their first request, by reason."""
        def count(reason: str) -> None:
            if self.metrics is not None:
                self.metrics.count_connection_refused(protocol, reason)
        return count

    def _count_ads(self, command: str, refused: str | None) -> None:
        """Every ADS request, for the metrics: by command, and refused ones by reason."""
        self._count("ads", command, refused)

    def _count(self, protocol: str, function: str, refused: str | None) -> None:
        if self.metrics is not None:
            self.metrics.count_request(protocol, function)
            if refused is not None:
                self.metrics.count_refused(protocol, refused)

    async def _add(self, part) -> None:
        await part.start()
        self.parts.append(part)

    def stats(self) -> dict:
        """What the parts counted that the service's ``--stats-json`` reports (the robot road's answers)."""
        return {p.protocol: p.stats() for p in self.parts if hasattr(p, "stats")}

    async def stop(self) -> None:
        self.final_stats = self.stats()
        for part in reversed(self.parts):
            try:
                await part.stop()
            except Exception as e:  # noqa: BLE001 - one failing part must not keep the others running
                log.error("stopping %s failed: %r", type(part).__name__, e)
        self.parts = []

    def part(self, kind: type) -> Any:
        return next((p for p in self.parts if isinstance(p, kind)), None)


class _Ads:
    """The ADS server as a part of the I/O server (a bind failure is a PlcError naming the address)."""

    protocol = "ads"

    def __init__(self, image: ProcessImage, settings, on_request=None):
        from plc_link.ads import AdsServer

        self.settings = settings
        self.server = AdsServer(image, settings, on_request=on_request)

    @property
    def clients(self) -> int:
        return len(self.server.connections)

    async def start(self) -> None:
        try:
            await self.server.start()
        except OSError as e:
            from io_base.listen import explain

            h, p = self.settings.host, self.settings.port
            raise PlcError(f"cannot serve ADS on {h}:{p}: {explain(e, h, p, 'ads.port')}") from e
        log.info("ADS server on %s:%d, AMS Net ID %s, port %d", self.settings.host, self.settings.port,
                 self.settings.net_id, self.settings.ams_port)

    async def stop(self) -> None:
        await self.server.stop()


async def _serve(server: IoServer, started: threading.Event | None, stop_requested) -> None:
    await server.start()
    if started is not None:
        started.set()
    try:
        while not stop_requested():
            await asyncio.sleep(0.05)
    finally:
        await server.stop()


class IoThread:
    """The `IoServer` on an asyncio loop in a thread of this process (tests only; production uses
    `io_process.process.IoProcess`, which runs the same server)."""

    def __init__(self, image: ProcessImage, settings: IoSettings):
        self.server = IoServer(image, settings)
        self._stop = threading.Event()
        self._started = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name="stiffcomp-io", daemon=True)

    def _run(self) -> None:
        try:
            asyncio.run(_serve(self.server, self._started, self._stop.is_set))
        except BaseException as e:  # noqa: BLE001 - reported to start()
            self._error = e
            self._started.set()

    def start(self, timeout: float = 10.0) -> None:
        self._thread.start()
        if not self._started.wait(timeout):
            self.stop()
            raise PlcError("the I/O server did not start in time")
        if self._error is not None:
            self.stop()
            raise self._error if isinstance(self._error, PlcError) else PlcError(str(self._error))

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(10.0)
