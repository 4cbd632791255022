"""The ADS server's settings: the ``ads:`` section of the service config (docs/ads.md)."""

from __future__ import annotations

import ipaddress

from pydantic import Field, field_validator

from io_base.settings import ClientLimits, peer_address
from stiffness.files.yaml_schema import Strict

from .ams import SYSTEM_SERVICE_PORT, net_id_bytes


def _check_net_id(v: str) -> str:
    net_id_bytes(v)            # raises ValueError with the reason
    return v


class Route(Strict):
    """One allowed peer: requests from ``address`` whose source AMS Net ID is ``net_id``."""

    net_id: str
    address: str

    _net_id = field_validator("net_id")(_check_net_id)

    @field_validator("address")
    @classmethod
    def _ip(cls, v: str) -> str:
        return str(ipaddress.ip_address(v))


class AdsSettings(ClientLimits):
    """Where the server listens, who it is, who may talk to it, and its limits.

    Attributes
    ----------
    enabled : serve ADS from the I/O process (on by default, as a TwinCAT runtime answers ADS)
    host, port : TCP bind address; 48898 is the AMS/TCP port every ADS client connects to
    net_id, ams_port : the server's AMS address (127.0.0.1.1.1:851, TwinCAT 3's first PLC runtime)
    allow_loopback : accept any AMS Net ID from a loopback address (127.0.0.0/8, ::1)
    routes : further peers, each an AMS Net ID and its IP address; anyone else is disconnected
    max_clients, first_frame_timeout_s, idle_timeout_s : the client limits (`ClientLimits`): when all
        places are taken, the longest-idle connection gives way to a new one; a connection with
        notifications is not idle
    max_handles, max_notifications : per connection (ADS error 0x716 beyond)
    max_sum_requests : sub-requests in one sum command (pyads sends at most 500)
    max_frame_bytes : longest AMS frame accepted; a longer announced length closes the connection
    frame_timeout_s : s, a frame begun must be complete within this, or the connection is closed
    max_send_buffer : bytes queued to a client that does not read; notifications to it are skipped
        beyond this, so a stalled client cannot grow the server's memory
    notify_poll_s : s, how often the server checks the image for a new cycle while notifications exist
    log_interval_s : s, protocol errors are logged once per client and reason per interval
    """

    enabled: bool = True
    host: str = "127.0.0.1"
    port: int = Field(48898, ge=0, le=65535)
    net_id: str = "127.0.0.1.1.1"
    ams_port: int = Field(851, ge=1, le=65535)
    allow_loopback: bool = True
    routes: list[Route] = Field(default_factory=list)
    max_handles: int = Field(1024, ge=1)
    max_notifications: int = Field(256, ge=1)
    max_sum_requests: int = Field(500, ge=1)
    max_frame_bytes: int = Field(1 << 20, ge=1024)
    frame_timeout_s: float = Field(10.0, gt=0)
    max_send_buffer: int = Field(1 << 20, ge=1024)
    notify_poll_s: float = Field(0.001, gt=0, le=0.1)
    log_interval_s: float = Field(10.0, gt=0)
    device_name: str = Field("stiffcomp", max_length=15)

    _net_id = field_validator("net_id")(_check_net_id)

    @field_validator("ams_port")
    @classmethod
    def _not_system(cls, v: int) -> int:
        if v == SYSTEM_SERVICE_PORT:
            raise ValueError(f"{v} is the system service's AMS port; the PLC runtime needs another (851)")
        return v

    def allows(self, peer_ip: str, net_id: str | None = None) -> bool:
        """Whether ``peer_ip`` (and, once known, the source ``net_id`` it sends) is a known route."""
        ip = peer_address(peer_ip)
        if self.allow_loopback and ip.is_loopback:
            return True
        return any(str(ip) == r.address and (net_id is None or net_id == r.net_id) for r in self.routes)

    def client_net_id(self, peer_ip: str) -> str:
        """The AMS Net ID a client at ``peer_ip`` is given when it asks the router for an address (port
        connect): its route's, or, on this machine without one, the server's own, as TwinCAT's router
        gives its local clients."""
        ip = str(peer_address(peer_ip))
        return next((r.net_id for r in self.routes if r.address == ip), self.net_id)

