"""What every listener's settings share: ports, peers and their addresses, TLS and the client limits.

Each is a strict pydantic model (unknown keys, inf and NaN refused); `plc_link.settings`, `plc_link.ads.settings`,
`robot_road.settings` and `io_process.settings` build the config's sections from them.
"""

from __future__ import annotations

import ipaddress
from typing import Literal

from pydantic import Field, model_validator

from stiffness.files.yaml_schema import Strict

IpAddress = ipaddress.IPv4Address | ipaddress.IPv6Address
Access = Literal["none", "read", "write"]
PORT_MIN, PORT_MAX = 1, 65535


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
