"""The I/O side of the service: one asyncio loop serving every protocol from the process image.

`IoServer` mounts, on one loop, the Modbus TCP server (or the Modbus client role, which writes into a
PLC's TF6250 registers), the ADS server and the monitoring endpoint. It meets the cycle only in the
`ProcessImage`. In production it runs in a process of its own (`IoProcess`, the only layout `stiffcomp
run` uses); `IoThread` runs the very same `IoServer` on a loop in a thread of the caller, for tests of
the protocols without a service.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from dataclasses import dataclass, field
from typing import Any

from .errors import PlcError
from .image import ProcessImage
from .settings import PlcSettings

log = logging.getLogger("stiffcomp.io")


@dataclass
class IoSettings:
    """What the I/O process serves: the PLC role, and the optional ADS and monitoring sections."""

    plc: PlcSettings = field(default_factory=PlcSettings)
    ads: Any = None                 # plc_interface.ads.AdsSettings, or None (no ADS server)
    monitoring: Any = None          # plc_interface.settings.MonitoringSettings, or None
    robot: Any = None               # plc_interface.robot.road.RoadSettings, or None (no robot road)
    avoid_cpu: int | None = None    # keep the I/O process off the cycle's CPU when it is pinned


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
        """Start every part; on failure the parts already started are stopped and PlcError is raised."""
        s = self.settings
        try:
            if s.plc.role == "server":
                await self._modbus_servers(s.plc)
            elif s.plc.role == "client":
                from .modbus_client import ModbusClient

                c = s.plc.client
                await self._add(ModbusClient(self.image, s.plc.host, s.plc.port, s.plc.device_id,
                                             c.period_ms / 1000.0, c.timeout_s, c.write_start, c.read_table,
                                             c.read_start))
            if s.robot is not None and s.robot.robot.enabled:
                from .robot.road import RobotRoad

                await self._add(RobotRoad(self.image, s.robot, self.metrics))
            if s.ads is not None and s.ads.enabled:
                await self._add(_Ads(self.image, s.ads, self._count_ads))
            if s.monitoring is not None and s.monitoring.enabled:
                from .monitoring import Monitor

                await self._add(Monitor(self.image, s.monitoring, self.metrics, parts=lambda: self.parts))
        except BaseException:
            await self.stop()
            raise

    async def _modbus_servers(self, plc: PlcSettings) -> None:
        """Plain Modbus TCP on ``plc.port`` (unless TLS alone) and Modbus/TCP Security on ``plc.tls.port``."""
        from .modbus_server import ModbusServer

        if not plc.tls.enabled or plc.tls.plain:
            warning = plc.exposure_warning()
            if warning:
                log.warning(warning)
            await self._add(ModbusServer(self.image, plc.host, plc.port, self._count_modbus, limits=plc,
                                         on_connection_refused=self._count_connection("modbus")))
        if plc.tls.enabled:
            from .tls import ServerTls

            await self._add(ModbusServer(self.image, plc.host, plc.tls.port, self._count_modbus_tls, limits=plc,
                                         tls=ServerTls(plc.tls), on_connection_refused=self._count_connection("modbus_tls")))

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
        from .ads import AdsServer

        self.settings = settings
        self.server = AdsServer(image, settings, on_request=on_request)

    @property
    def clients(self) -> int:
        return len(self.server.connections)

    async def start(self) -> None:
        try:
            await self.server.start()
        except OSError as e:
            from .listen import explain

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
    `plc_interface.io_process.IoProcess`, which runs the same server)."""

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
