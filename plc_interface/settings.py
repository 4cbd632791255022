"""The config sections of the PLC side (``plc:``), owned here and mounted in the service config.

Each section is a strict pydantic model (unknown keys, inf and NaN refused); the service config
(`service.config.ServiceConfig`) composes them, and the I/O process receives them as they are.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from stiffness.yamlio import Strict

from .endpoints import PLC_ROLES, PORT_MAX, PORT_MIN, MonitoringEndpoint, PlcEndpoint


class PlcClientSettings(Strict):
    period_ms: float = Field(10.0, ge=1.0, le=1000.0)
    timeout_s: float = Field(1.0, gt=0, le=60.0)
    write_start: int = Field(0x3000, ge=0, le=0xFFFF)
    read_table: Literal["input_registers", "holding_registers"] = "input_registers"
    read_start: int = Field(0x8000, ge=0, le=0xFFFF)


class ClientLimits(Strict):
    """How many TCP clients a server holds and how long a silent one may stay (`client_table`).

    Attributes
    ----------
    max_clients : connections at once; when full, the longest-idle one gives way to a new one
    first_frame_timeout_s : s, a new connection must send a complete request within this
    idle_timeout_s : s, a connection without a request for this long is closed (0: never)
    """

    max_clients: int = Field(64, ge=1, le=10_000)
    first_frame_timeout_s: float = Field(10.0, gt=0, le=3600)
    idle_timeout_s: float = Field(300.0, ge=0, le=86_400)


class PlcSettings(ClientLimits):
    """The ``plc:`` section; the client limits apply to the Modbus server (role ``server``). The
    defaults a probe reads are `PlcEndpoint`'s."""

    role: Literal[PLC_ROLES] = PlcEndpoint.role
    host: str = PlcEndpoint.host
    port: int = Field(PlcEndpoint.port, ge=PORT_MIN, le=PORT_MAX)
    device_id: int = Field(1, ge=0, le=247)
    register_map: str = PlcEndpoint.register_map
    initial_q_deg: list[float] = Field(default_factory=lambda: [0.0, -90.0, 90.0, 0.0, 45.0, 0.0],
                                       min_length=6, max_length=6)
    enable_on_start: bool = False
    client: PlcClientSettings = Field(default_factory=PlcClientSettings)


class MonitoringSettings(Strict):
    """The I/O process's HTTP endpoint: /health, /health/live and /health/ready always, /metrics
    (Prometheus) when ``metrics``. The defaults a probe reads are `MonitoringEndpoint`'s."""

    enabled: bool = MonitoringEndpoint.enabled
    host: str = MonitoringEndpoint.host
    port: int = Field(MonitoringEndpoint.port, ge=PORT_MIN, le=PORT_MAX)
    metrics: bool = False
    health_max_exceed_rate: float = Field(MonitoringEndpoint.health_max_exceed_rate, ge=0.0, le=1.0)
