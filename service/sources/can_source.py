"""A live ATI sensor on a CAN bus, through python-can (any interface it supports: socketcan, pcan,
kvaser, vector, virtual, udp_multicast, ...).

With ``request_each_cycle``, the short-data request for cycle k is sent ``request_lead_us`` before
cycle k's deadline (the task calls `CanSource.request` then, between two cycles), and cycle k drains the
frames received since: the sensor's answer is read in the cycle it was requested for, not one period
later. With ``request_lead_us: 0`` the request is sent in the cycle and answered in the next one.
"""

from __future__ import annotations

from collections.abc import Iterable

import can
from pydantic import Field

from stiffness.errors import quote
from stiffness.files.yaml_schema import Strict

from ..errors import SourceError
from .base import Frame, FtSource

MAX_FRAMES_PER_CYCLE = 64   # bounds the work of one cycle if the bus floods


def open_bus(interface: str, channel: str, bitrate: int | None = None, **options) -> can.BusABC:
    """Open a python-can bus; SourceError names the interface and channel on failure."""
    kw = dict(options)
    if bitrate is not None and interface not in ("virtual", "udp_multicast"):
        kw["bitrate"] = bitrate
    try:
        return can.Bus(interface=interface, channel=channel, **kw)
    except (can.CanError, OSError, ValueError, ImportError, NotImplementedError) as e:
        raise SourceError(f"cannot open CAN interface {quote(interface)} channel {quote(channel)}: {e}") from e



class CanConfig(Strict):
    """``source.can``: the python-can bus the sensor is on (interface, channel, bitrate, options)."""

    interface: str = "virtual"
    channel: str = "ati0"
    bitrate: int | None = Field(1_000_000, gt=0)
    request_each_cycle: bool = True
    request_lead_us: float = Field(400.0, ge=0.0, le=5000.0)
    options: dict[str, str | int | float | bool] = Field(default_factory=dict)

class CanSource(FtSource):
    """F/T samples from a live bus.

    Parameters
    ----------
    bus : can.BusABC
        An open bus; the source owns it and shuts it down on close().
    request_each_cycle : bool
        Send a short-data request (0x02) every cycle; off for sensors that stream by themselves.
    request_lead_s : float
        Send it this long before the cycle's deadline (`request`, called by the task), so the answer is
        read in that cycle; 0: send it in the cycle (`_frames`), read in the next.
    """

    def __init__(self, bus: can.BusABC, request_each_cycle: bool = True, request_lead_s: float = 0.0, **kw):
        super().__init__(**kw)
        self.bus = bus
        self.request_each_cycle = request_each_cycle
        self.lead_s = float(request_lead_s) if request_each_cycle else 0.0
        arb, data = self.protocol.request_short_data()
        self._request = can.Message(arbitration_id=arb, data=data, is_extended_id=False)

    @classmethod
    def from_config(cls, section, timeout_s: float, resolve) -> CanSource:
        c = section.can
        bus = open_bus(c.interface, c.channel, c.bitrate, **c.options)
        return cls(bus, c.request_each_cycle, c.request_lead_us * 1e-6, **cls.common_args(section, timeout_s))

    def _frames(self, t: float) -> Iterable[Frame]:
        out: list[Frame] = []
        recv = self.bus.recv
        for _ in range(MAX_FRAMES_PER_CYCLE):
            msg = recv(0.0)
            if msg is None:
                break
            out.append((msg.arbitration_id, bytes(msg.data), msg.is_error_frame))
        if self.request_each_cycle and not self.lead_s:
            self._send(self._request)
        return out

    def request(self) -> None:
        """The short-data request, ``lead_s`` before the cycle that reads its answer (the task calls it)."""
        self._send(self._request)

    def _send(self, msg: can.Message) -> None:
        try:
            self.bus.send(msg, timeout=0.0)
        except can.CanError:
            pass            # a full TX queue shows up as a sensor timeout, which is the fault

    def request_bias(self) -> None:
        arb, data = self.protocol.request_bias()
        self._send(can.Message(arbitration_id=arb, data=data, is_extended_id=False))

    def close(self) -> None:
        self.bus.shutdown()
