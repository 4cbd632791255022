"""The AMS router's own commands: a client without a router of its own first asks for an AMS address.

The first two bytes of an AMS/TCP header (``reserved`` in AdsLib's `AmsTcpHeader`) say what the frame
carries: 0 an AMS frame (`ams`); any other value a command to the router itself, whose data follows
the 6-byte header with no AMS header (ads-client's ``AMS_HEADER_FLAG``). A TwinCAT router serves these
on the same TCP port 48898, and so does this server:

- **0x1000 port connect**, sent by ads-client in its default mode before anything else: 2 bytes, the
  AMS port the client asks for (0: any). The answer has the same command and 8 bytes: the AMS Net ID
  the client is to use as its own, then the port lent to it (both the source address of its requests).
- **0x0001 port close**, sent by ads-client when it disconnects: 2 bytes, the port it gives back. The
  router then closes the connection, which is the end ads-client waits for.

0x1001 (router notification) and 0x1002 (local Net ID) go from a router to its clients, never to it,
and any other value is no command at all: the server closes such a connection, as it does a port
connect or close whose length is not 2 or a port close for a port the connection does not hold.
"""

from __future__ import annotations

import struct

from .ams import TCP_HEADER

AMS_FRAME, PORT_CLOSE, PORT_CONNECT = 0x0000, 0x0001, 0x1000
ROUTER_COMMANDS = {PORT_CONNECT: "PortConnect", PORT_CLOSE: "PortClose"}
PORT_REQ = struct.Struct("<H")              # the port asked for (connect) or given back (close)
PORT_RES = struct.Struct("<6sH")            # the client's AMS Net ID and its port
PORT_BASE = 30000                           # ports are lent from here up, as AdsLib's router numbers its own


def port_connect_reply(net_id: bytes, port: int) -> bytes:
    """The router's answer to a port connect: the client's AMS address."""
    return TCP_HEADER.pack(PORT_CONNECT, PORT_RES.size) + PORT_RES.pack(net_id, port)


class PortTable:
    """The AMS ports lent to connections, at most one each, never one the server answers on itself.

    Parameters
    ----------
    reserved : ports never lent (the PLC runtime's and the system service's)
    """

    def __init__(self, reserved: set[int]):
        self.reserved = set(reserved)
        self.lent: set[int] = set()

    def lend(self, wanted: int) -> int:
        """``wanted`` if it is free and not reserved, else the lowest free port from `PORT_BASE` up.

        Ports run out only beyond 35 000 connections; `ClientLimits.max_clients` allows at most 10 000.
        """
        if not wanted or wanted in self.lent or wanted in self.reserved:
            wanted = next(p for p in range(PORT_BASE, 0x10000) if p not in self.lent and p not in self.reserved)
        self.lent.add(wanted)
        return wanted

    def give_back(self, port: int | None) -> None:
        self.lent.discard(port)
