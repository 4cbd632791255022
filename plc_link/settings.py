"""The ``plc:`` section of the config, owned here and mounted in the service config.

A strict pydantic model (unknown keys, inf and NaN refused); the service config
(`service.config.ServiceConfig`) composes it, and the I/O process receives it as it is.
"""

from __future__ import annotations

import ipaddress
from typing import Literal

from pydantic import Field, field_validator

from io_base.settings import PORT_MAX, PORT_MIN, ClientLimits, TlsSettings, is_loopback, peer_address
from stiffness.files.yaml_schema import Strict

PLC_ROLES = ("server", "client", "none")


class PlcClientSettings(Strict):
    period_ms: float = Field(10.0, ge=1.0, le=1000.0)
    timeout_s: float = Field(1.0, gt=0, le=60.0)
    write_start: int = Field(0x3000, ge=0, le=0xFFFF)
    read_table: Literal["input_registers", "holding_registers"] = "input_registers"
    read_start: int = Field(0x8000, ge=0, le=0xFFFF)


class PlcSettings(ClientLimits):
    """The ``plc:`` section; the client limits apply to the Modbus server (role ``server``).

    ``writers``: the addresses or networks (CIDR) whose plain Modbus TCP clients may write; every other
    client may read, and its writes are answered with exception 01. None (the default): any client may
    write. Over TLS the client certificate's role decides (``tls``).
    """

    role: Literal[PLC_ROLES] = "server"
    host: str = "127.0.0.1"
    port: int = Field(5020, ge=PORT_MIN, le=PORT_MAX)
    device_id: int = Field(1, ge=0, le=247)
    register_map: str = "registers.yaml"
    initial_q_deg: list[float] = Field(default_factory=lambda: [0.0, -90.0, 90.0, 0.0, 45.0, 0.0],
                                       min_length=6, max_length=6)
    enable_on_start: bool = False
    writers: list[str] | None = None
    tls: TlsSettings = Field(default_factory=TlsSettings)
    client: PlcClientSettings = Field(default_factory=PlcClientSettings)

    @field_validator("writers")
    @classmethod
    def _networks(cls, v: list[str] | None) -> list[str] | None:
        return None if v is None else [str(ipaddress.ip_network(n, strict=False)) for n in v]

    def may_write(self, peer_ip: str) -> bool:
        """Whether a plain Modbus TCP client at ``peer_ip`` may write (``writers``)."""
        if self.writers is None:
            return True
        ip = peer_address(peer_ip)
        return any(ip in ipaddress.ip_network(n) for n in self.writers)

    def served(self) -> str:
        """What the PLC side serves, as the start-up line names it: ``server 127.0.0.1:5020`` (plain Modbus
        TCP), ``server 127.0.0.1:5020 and Modbus/TCP Security 127.0.0.1:802``, ``server Modbus/TCP Security
        127.0.0.1:802 alone``, ``client of 192.168.10.20:502``, ``none``."""
        if self.role != "server":
            return f"client of {self.host}:{self.port}" if self.role == "client" else self.role
        secure = f"Modbus/TCP Security {self.host}:{self.tls.port}"
        if not self.tls.enabled:
            return f"server {self.host}:{self.port}"
        return f"server {self.host}:{self.port} and {secure}" if self.tls.plain else f"server {secure} alone"

    def exposure_warning(self) -> str | None:
        """The warning for plain Modbus TCP served beyond this machine with no ``writers``, or None."""
        if (self.role != "server" or self.writers is not None or (self.tls.enabled and not self.tls.plain)
                or is_loopback(self.host)):
            return None
        return (f"plain Modbus TCP listens on {self.host}:{self.port} and plc.writers is not set: every host "
                "that reaches this port can write the command word (enable, tare, reset faults), the joint "
                "positions and the payload index; set plc.writers to the PLC's address (docs/security.md)")
