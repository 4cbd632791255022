"""The config sections of the PLC side (``plc:``), owned here and mounted in the service config.

Each section is a strict pydantic model (unknown keys, inf and NaN refused); the service config
(`service.config.ServiceConfig`) composes them, and the I/O process receives them as they are.
"""

from __future__ import annotations

import ipaddress
from typing import Literal

from pydantic import Field, field_validator, model_validator

from stiffness.files.yaml_schema import Strict

IpAddress = ipaddress.IPv4Address | ipaddress.IPv6Address
Access = Literal["none", "read", "write"]
PORT_MIN, PORT_MAX = 1, 65535
PLC_ROLES = ("server", "client", "none")


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


def peer_address(peer_ip: str) -> IpAddress:
    """A peer's address as allow-lists name it (an IPv4-mapped IPv6 address as IPv4, no zone)."""
    ip = ipaddress.ip_address(peer_ip.split("%")[0])
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped:
        return ip.ipv4_mapped
    return ip


def is_loopback(host: str) -> bool:
    """Whether a bind address ``host`` reaches only this machine (127.0.0.0/8, ::1, ``localhost``)."""
    try:
        return peer_address(host).is_loopback
    except ValueError:
        return host == "localhost"


class TlsSettings(Strict):
    """``plc.tls``: Modbus/TCP Security, Modbus TCP in TLS with client certificates (docs/security.md).

    Attributes
    ----------
    enabled : serve Modbus/TCP Security on ``port``
    port : 802, the protocol's registered port
    cert, key : the server's certificate (PEM, with its chain) and its unencrypted private key
    ca : the CA certificate(s) (PEM) that sign the client certificates; a client without a certificate
        from one of them is refused at the handshake
    plain : also serve plain Modbus TCP on ``plc.port`` (false: TLS alone)
    roles : access of each role a client certificate names (Modbus role extension,
        OID 1.3.6.1.4.1.50316.802.1): ``read``, ``write`` or ``none`` (closed after the handshake)
    default_access : access of a certificate without the role extension, or with a role not in ``roles``
    probe_cert, probe_key : a client certificate signed by ``ca`` (a role that may read) and its key, which
        `stiffcomp health` shows to ask over Modbus/TCP Security where nothing else serves it (TLS alone,
        HTTP off); the probe checks the server's certificate against ``ca``
    """

    enabled: bool = False
    port: int = Field(802, ge=1, le=65535)
    cert: str | None = None
    key: str | None = None
    ca: str | None = None
    plain: bool = True
    roles: dict[str, Access] = Field(default_factory=lambda: {"operator": "write", "viewer": "read"})
    default_access: Access = "read"
    probe_cert: str | None = None
    probe_key: str | None = None

    @model_validator(mode="after")
    def _files_when_enabled(self) -> TlsSettings:
        missing = [k for k in ("cert", "key", "ca") if getattr(self, k) is None]
        if self.enabled and missing:
            raise ValueError(f"enabled needs {', '.join(missing)} (stiffcomp certs makes a set, docs/security.md)")
        if (self.probe_cert is None) != (self.probe_key is None):
            raise ValueError("probe_cert and probe_key go together: a client certificate and its key")
        return self

    def files(self) -> dict[str, str]:
        """The files it names, by key (``cert``, ``key``, ``ca``, and ``probe_cert``, ``probe_key`` when
        set), when enabled."""
        keys = ("cert", "key", "ca") + (("probe_cert", "probe_key") if self.probe_cert is not None else ())
        return {k: getattr(self, k) for k in keys} if self.enabled else {}

    def access(self, role: str | None) -> Access:
        """What a client whose certificate names ``role`` (None: no role) may do."""
        return self.roles.get(role, self.default_access) if role is not None else self.default_access


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


class MonitoringSettings(Strict):
    """The I/O process's HTTP endpoint: /health, /health/live and /health/ready always, /metrics
    (Prometheus) when ``metrics``."""

    enabled: bool = True
    host: str = "127.0.0.1"
    port: int = Field(9020, ge=PORT_MIN, le=PORT_MAX)
    metrics: bool = False
    health_max_exceed_rate: float = Field(0.05, ge=0.0, le=1.0)
