"""The defaults of the service config's keys a probe reads, written once: the light reader
(`plc_interface.endpoints`) and the service's schemas (`plc_interface.settings`) both take them from here.
Standard library only.
"""

from __future__ import annotations

from dataclasses import dataclass

PORT_MIN, PORT_MAX = 1, 65535
PLC_ROLES = ("server", "client", "none")


@dataclass(frozen=True)
class MonitoringEndpoint:
    """The ``monitoring`` keys a probe reads, with their defaults (the schema: `MonitoringSettings`)."""

    enabled: bool = True
    host: str = "127.0.0.1"
    port: int = 9020
    health_max_exceed_rate: float = 0.05


@dataclass(frozen=True)
class PlcEndpoint:
    """The ``plc`` keys a probe reads, with their defaults (the schema: `PlcSettings`)."""

    role: str = "server"
    host: str = "127.0.0.1"
    port: int = 5020
    register_map: str = "registers.yaml"
