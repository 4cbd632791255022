"""The server as the client's AMS router: port connect (0x1000) lends an AMS address, port close (0x0001)
gives it back and ends the connection, anything malformed closes the connection and no other. Raw
frames against the server in a spawn child; ads-client doing the same in its default mode:
test_ads_node.py."""

from __future__ import annotations

import socket
import struct
import time

import pytest

from plc_link.ads import AdsSettings, ams
from plc_link.ads.router import PORT_BASE
from testlib.ads_child import AdsChild, recv_exact

pytestmark = pytest.mark.realtime

NET_ID = "5.6.7.13.1.1"
ROUTED = "10.0.0.9.1.1"


def connect(child: AdsChild) -> socket.socket:
    return socket.create_connection((child.host, child.port), timeout=10.0)     # a hang fails, nothing timed


def router_frame(command: int, data: bytes, length: int | None = None) -> bytes:
    return ams.TCP_HEADER.pack(command, len(data) if length is None else length) + data


def port_connect(s: socket.socket, wanted: int = 0) -> tuple[str, int]:
    """Ask for an AMS address as ads-client does; the (Net ID, port) answered."""
    s.sendall(router_frame(0x1000, struct.pack("<H", wanted)))
    command, length = ams.TCP_HEADER.unpack(recv_exact(s, 6))
    assert (command, length) == (0x1000, 8)
    net_id, port = struct.unpack("<6sH", recv_exact(s, 8))
    return ams.net_id_text(net_id), port


def read_state(s: socket.socket, source: str, source_port: int, invoke: int = 5) -> tuple[int, int]:
    """ReadState on port 851 from the given address: (AMS error, ADS state)."""
    s.sendall(ams.request_frame(ams.net_id_bytes(NET_ID), 851, ams.net_id_bytes(source), source_port,
                                ams.READ_STATE, b"", invoke))
    _, length = ams.TCP_HEADER.unpack(recv_exact(s, 6))
    body = recv_exact(s, length)
    h = ams.AmsHeader.parse(body)
    assert (h.invoke_id, h.target, h.target_port) == (invoke, ams.net_id_bytes(source), source_port)
    return h.error, ams.STATE_RES.unpack(body[32:])[1] if not h.error else 0


def lent_again(child: AdsChild, wanted: int, deadline_s: float = 30.0) -> bool:
    """Whether ``wanted`` is lent to a new connection once the server has noticed the last one's end."""
    end = time.monotonic() + deadline_s
    while time.monotonic() < end:
        with connect(child) as s:
            if port_connect(s, wanted)[1] == wanted:
                return True
        time.sleep(0.01)
    return False


def closed(s: socket.socket) -> bool:
    """Whether the server ends the connection (without sending anything first)."""
    return s.recv(100) == b""


@pytest.fixture
def child(tmp_path):
    log = tmp_path / "ads.log"
    with AdsChild(net_id=NET_ID, log_path=str(log)) as c:
        c.log = log
        yield c


def test_port_connect_lends_the_servers_net_id_and_a_free_port_then_requests_go_through(child):
    with connect(child) as a, connect(child) as b:
        net_a, port_a = port_connect(a)
        assert net_a == NET_ID                      # from this machine: the router's own Net ID, as TwinCAT
        assert port_connect(a) == (net_a, port_a)   # one address per connection: asked again, the same
        net_b, port_b = port_connect(b, wanted=port_a)     # taken: another one
        assert net_b == NET_ID and port_b != port_a and PORT_BASE <= min(port_a, port_b)
        assert read_state(a, net_a, port_a) == (0, ams.ADSSTATE_RUN)
        assert read_state(b, net_b, port_b) == (0, ams.ADSSTATE_RUN)
        with connect(child) as c:
            assert port_connect(c, wanted=40123)[1] == 40123        # free: the one asked for
            for reserved in (851, 10000):                           # the server's own ports are never lent
                with connect(child) as d:
                    assert port_connect(d, wanted=reserved)[1] not in (851, 10000, 40123, port_a, port_b)


def test_port_close_gives_the_port_back_and_ends_the_connection(child):
    with connect(child) as a:
        _, port = port_connect(a, wanted=41000)
        a.sendall(router_frame(0x0001, struct.pack("<H", port)))
        assert closed(a)
    with connect(child) as b:                       # given back before the close: lent again at once
        assert port_connect(b, wanted=41000)[1] == 41000
    assert lent_again(child, 41000)                 # a connection that ends without port close gives it back too


MALFORMED = [
    router_frame(0x1000, b""),                      # port connect not of 2 bytes
    router_frame(0x1000, b"\0"),
    router_frame(0x1000, b"\0\0\0"),
    router_frame(0x1000, b"", length=0xFFFFFFFF),
    router_frame(0x0001, struct.pack("<H", 30000)),  # port close before any port connect
    router_frame(0x0001, b"\0\0\0\0"),
    router_frame(0x1001, b"\0\0\0\0"),              # router notification: from a router, never to it
    router_frame(0x1002, b""),                      # local Net ID request
    router_frame(0x0002, struct.pack("<H", 0)),
    router_frame(0xFFFF, b""),
]


def test_malformed_router_frames_close_that_connection_only(child):
    with connect(child) as bystander:
        net, port = port_connect(bystander)
        for k, frame in enumerate(MALFORMED):
            with connect(child) as s:
                s.sendall(frame)
                assert closed(s), frame.hex()
            assert read_state(bystander, net, port, invoke=k) == (0, ams.ADSSTATE_RUN)
    text = child.log.read_text()
    assert "AMS/TCP port connect or close not of 2 bytes (closed)" in text
    assert "AMS/TCP command that is no AMS frame, port connect or port close (closed)" in text


def test_port_close_of_a_port_not_held_closes_and_the_held_one_is_given_back(child):
    with connect(child) as a:
        _, port = port_connect(a, wanted=42000)
        a.sendall(router_frame(0x0001, struct.pack("<H", port + 1)))
        assert closed(a)
    with connect(child) as b:
        assert port_connect(b, wanted=42000)[1] == 42000
    assert "port close for a port this connection does not hold (closed)" in child.log.read_text()


def test_a_routed_client_is_given_its_routes_net_id_and_is_served_with_it():
    routes = [{"net_id": ROUTED, "address": "127.0.0.1"}]
    with AdsChild(net_id=NET_ID, allow_loopback=False, routes=routes) as child, connect(child) as s:
        net, port = port_connect(s)
        assert net == ROUTED
        assert read_state(s, net, port) == (0, ams.ADSSTATE_RUN)


def test_client_net_id_is_the_routes_for_its_address_else_the_servers():
    s = AdsSettings(net_id=NET_ID, routes=[{"net_id": ROUTED, "address": "192.168.1.20"}])
    assert s.client_net_id("192.168.1.20") == s.client_net_id("::ffff:192.168.1.20") == ROUTED
    assert s.client_net_id("127.0.0.1") == s.client_net_id("::1") == NET_ID
