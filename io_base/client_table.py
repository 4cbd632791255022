"""Who may hold one of a server's TCP connections: the one policy of the ADS and the Modbus server.

A client that connects must send a complete request within ``first_frame_timeout_s``, and one that has
sent none for ``idle_timeout_s`` is closed (0: never), unless it is ``busy`` (an ADS client that
holds notifications is being served while it says nothing). When all ``max_clients`` places are
taken, a newcomer does not get refused: the longest-idle client gives way, first those that never
sent a request, oldest first, then those with notifications last. A client that sent a request
within the last ``POLLING_S`` is polling and never gives way, so the PLC, which polls every few
milliseconds, keeps its connection; only when every place is held by a polling client is the
newcomer refused.

The table reads the clock, once per event, through ``clock`` (tests pass their own).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

POLLING_S = 1.0         # s: a client that sent a request this recently is polling and keeps its place


@dataclass(eq=False)
class Client:
    """One connection: ``close`` ends it (without waiting), ``busy`` tells whether silence is idleness."""

    peer: str
    close: Callable[[], None]
    busy: Callable[[], bool]
    connected_at: float
    last_request: float | None = None
    closed_for: str = field(default="", init=False)


class ClientTable:
    """The connections of one server.

    Parameters
    ----------
    limits : anything with ``max_clients``, ``first_frame_timeout_s`` and ``idle_timeout_s``
        (`io_base.settings.ClientLimits`)
    on_close : callable (client, reason) -> None, told of every client the table closes
    clock : monotonic seconds
    """

    def __init__(self, limits, on_close: Callable[[Client, str], None] = lambda c, r: None,
                 clock: Callable[[], float] = time.monotonic):
        self.max_clients = limits.max_clients
        self.first_frame_timeout_s = limits.first_frame_timeout_s
        self.idle_timeout_s = limits.idle_timeout_s
        self.on_close, self.clock = on_close, clock
        self.clients: list[Client] = []

    def add(self, peer: str, close: Callable[[], None], busy: Callable[[], bool] = lambda: False) -> Client | None:
        """Admit a new connection, closing the longest-idle one if the table is full; None if every
        place is held by a polling client (the caller closes the newcomer)."""
        now = self.clock()
        if len(self.clients) >= self.max_clients:
            idle = [c for c in self.clients if c.last_request is None or now - c.last_request >= POLLING_S]
            if not idle:
                return None
            victim = min(idle, key=lambda c: (c.busy(), c.last_request is not None, c.last_request or c.connected_at))
            self._close(victim, "gave way to a new client (max_clients reached)")
        client = Client(peer, close, busy, now)
        self.clients.append(client)
        return client

    def request(self, client: Client) -> None:
        """``client`` sent a complete request."""
        client.last_request = self.clock()

    def remove(self, client: Client | None) -> None:
        """The connection ended (by the client, or by the server for any reason); idempotent."""
        if client is not None and client in self.clients:
            self.clients.remove(client)

    def sweep(self) -> None:
        """Close the clients that sent no request in time after connecting, or have been idle too long."""
        now = self.clock()
        for c in list(self.clients):
            if c.last_request is None and now - c.connected_at > self.first_frame_timeout_s:
                self._close(c, "no request within first_frame_timeout_s (closed)")
            elif (c.last_request is not None and self.idle_timeout_s and now - c.last_request > self.idle_timeout_s
                  and not c.busy()):
                self._close(c, "idle beyond idle_timeout_s (closed)")

    @property
    def sweep_interval_s(self) -> float:
        """How often `sweep` should run: a quarter of the shortest timeout, between 0.05 and 1 s."""
        shortest = min(t for t in (self.first_frame_timeout_s, self.idle_timeout_s) if t)
        return min(max(shortest / 4, 0.05), 1.0)

    def _close(self, client: Client, reason: str) -> None:
        self.remove(client)
        client.closed_for = reason
        self.on_close(client, reason)
        client.close()
