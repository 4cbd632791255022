"""Random and mutated AMS/TCP frames, and commands to the AMS router (port connect and close, well-formed
or not), from several connections (hypothesis): the ADS server answers or
closes each, serves a well-behaved pyads client throughout, never writes outside the PLC's registers,
and its log stays small."""

from __future__ import annotations

import socket
import struct
import time

import pyads
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from plc_link.ads import ams
from plc_link.register_map import RegisterMap
from testlib.ads_child import MAP, AdsChild, recv_exact

pytestmark = pytest.mark.realtime

NET_ID = "5.6.7.9.1.1"
TARGET = ams.net_id_bytes(NET_ID)
SOURCE = ams.net_id_bytes("127.0.0.1.1.1")
GROUPS = [0x4020, 0x4040, 0xF003, 0xF005, 0xF006, 0xF009, 0xF00B, 0xF00C, 0xF00F, 0xF080, 0xF081, 0xF082, 0x4021,
          0xF100, 0xF008, 0xF00E, 0xF011, 0xF0]
PORTS = [851, 851, 10000, 852]      # the PLC runtime, the system service, and a port nobody serves
# small numbers, the edges of the PLC's block in %MB (bytes 512..539: command word, heartbeat, q1..q6),
# limits, and anything
u32 = st.one_of(st.integers(0, 64), st.integers(508, 544), st.sampled_from([0x7FFFFFFF, 0xFFFFFFFF, 1024, 1023, 500, 501]),
                st.integers(0, 0xFFFFFFFF))
group = st.one_of(st.sampled_from(GROUPS), st.integers(0, 0xFFFFFFFF))
blob = st.binary(max_size=64)
names = st.sampled_from([b"GVL_Comp.q1\0", b"GVL_Comp.NoSuchSymbol", b"gvl_comp.command_word", b"\xff\xfe", b"",
                         b"REAL\0", b"udint", b"ST_NoSuchType\0"])


@st.composite
def payloads(draw) -> tuple[int, bytes]:
    if draw(st.integers(0, 5)) == 0:        # a write at the PLC's block, whole registers or not
        data = draw(st.binary(min_size=1, max_size=8))
        return ams.WRITE, struct.pack("<III", 0x4020, draw(st.integers(508, 544)), len(data)) + data
    cmd = draw(st.sampled_from([1, 2, 3, 4, 5, 6, 7, 8, 9, 0, 10, 0xFFFF]))
    g, off = draw(group), draw(u32)
    if cmd == ams.READ:
        return cmd, struct.pack("<III", g, off, draw(u32))
    if cmd == ams.WRITE:
        data = draw(blob)
        return cmd, struct.pack("<III", g, off, draw(st.one_of(st.just(len(data)), u32))) + data
    if cmd == ams.READ_WRITE:
        data = draw(st.one_of(blob, names, st.binary(min_size=12, max_size=48)))
        return cmd, struct.pack("<IIII", g, off, draw(u32), draw(st.one_of(st.just(len(data)), u32))) + data
    if cmd == ams.ADD_NOTIFICATION:
        return cmd, struct.pack("<IIIIII16x", g, off, draw(u32), draw(st.integers(0, 8)), draw(u32), draw(u32))
    return cmd, draw(blob)


@st.composite
def router_frames(draw) -> bytes:
    """Commands to the AMS router itself: port connect (0x1000) and close (0x0001), well-formed or not, and
    commands that go from a router, never to it (0x1001, 0x1002), or are none."""
    command = draw(st.sampled_from([0x1000, 0x1000, 0x0001, 0x0001, 0x1001, 0x1002, 0x0002, 0xFFFF]))
    data = draw(st.one_of(st.sampled_from([struct.pack("<H", p) for p in (0, 30000, 30001, 851, 10000, 0xFFFF)]),
                          st.binary(min_size=2, max_size=2), st.binary(max_size=10)))
    length = draw(st.one_of(st.just(len(data)), st.just(len(data)), u32))
    return ams.TCP_HEADER.pack(command, length) + data


@st.composite
def frames(draw) -> bytes:
    if draw(st.integers(0, 5)) == 0:
        return draw(router_frames())
    cmd, payload = draw(payloads())
    invoke = draw(st.integers(0, 0xFFFFFFFF))
    frame = ams.request_frame(TARGET, draw(st.sampled_from(PORTS)), SOURCE, 30000, cmd, payload, invoke)
    how = draw(st.sampled_from(["as is", "as is", "flip", "cut", "extend", "random", "header fields"]))
    if how == "flip":
        b = bytearray(frame)
        for _ in range(draw(st.integers(1, 4))):
            b[draw(st.integers(0, len(b) - 1))] = draw(st.integers(0, 255))
        frame = bytes(b)
    elif how == "cut":
        frame = frame[: draw(st.integers(0, len(frame) - 1))]
    elif how == "extend":
        frame += draw(st.binary(min_size=1, max_size=16))
    elif how == "random":
        frame = draw(st.binary(max_size=80))
    elif how == "header fields":       # a whole frame whose AMS fields lie: length, target, port, flags
        length = draw(st.one_of(st.just(len(payload)), u32))
        flags = draw(st.sampled_from([4, 5, 0, 0x44]))
        head = ams.AMS_HEADER.pack(draw(st.sampled_from([TARGET, SOURCE])), draw(st.sampled_from(PORTS)),
                                   SOURCE, 30000, cmd, flags, length, 0, invoke)
        frame = ams.TCP_HEADER.pack(0, 32 + len(payload)) + head + payload
    return frame


def delimited(frame: bytes) -> bool:
    """Whether the frame is whole by its AMS/TCP header, so the server must answer it (or close)."""
    if len(frame) < 6:
        return False
    command, length = ams.TCP_HEADER.unpack_from(frame)
    return command in (0, 0x1000, 0x0001) and length == len(frame) - 6


def answered_or_closed(s: socket.socket, frame: bytes) -> str:
    """Wait for the reply to ``frame`` (skipping notifications) or the end of the connection."""
    if not delimited(frame):
        s.shutdown(socket.SHUT_WR)            # nothing more will come: the server must answer what it can, then close
        while s.recv(65536):
            pass
        return "closed"
    invoke = struct.unpack_from("<I", frame, 6 + 28)[0] if len(frame) >= 38 else None
    while True:
        head = recv_exact(s, 6)
        if head is None:
            return "closed"
        command, length = ams.TCP_HEADER.unpack(head)
        body = recv_exact(s, length)
        if body is None:
            return "closed"
        if command == 0x1000:                   # the router's answer to port connect: the client's address
            assert frame[:2] == head[:2] and length == 8, (frame.hex(), head.hex())
            net_id, port = struct.unpack("<6sH", body)
            assert net_id == TARGET and port not in (851, 10000), body.hex()     # loopback: the server's Net ID
            return "port lent"
        assert command == 0, head.hex()
        h = ams.AmsHeader.parse(body)
        if h.flags & ams.FLAG_RESPONSE:
            assert h.invoke_id == invoke
            return "answered"


def lowest_port_lent(child: AdsChild, deadline_s: float = 30.0) -> int:
    """The port a port connect asking for any is lent once 30000 is free again (the server notices a
    closed connection a moment after the client closed it); the last one lent when the deadline passes."""
    end = time.monotonic() + deadline_s
    while True:
        with connect(child.host, child.port) as s:
            s.sendall(ams.TCP_HEADER.pack(0x1000, 2) + b"\0\0")
            head = recv_exact(s, 6)
            port = struct.unpack("<6sH", recv_exact(s, 8))[1]
        assert head == ams.TCP_HEADER.pack(0x1000, 8)
        if port == 30000 or time.monotonic() > end:
            return port
        time.sleep(0.01)


def connect(host: str, port: int) -> socket.socket:
    s = socket.create_connection((host, port), timeout=10.0)     # a hang fails the test; no timing asserted
    return s


def test_fuzzed_frames_are_answered_or_closed_and_a_good_client_is_served(tmp_path, record_property):
    log = tmp_path / "ads.log"
    tally = {"frames": 0, "answered": 0, "closed": 0, "port lent": 0, "good reads": 0, "answered by port 10000": 0}
    with AdsChild(net_id=NET_ID, log_path=str(log), log_interval_s=10.0) as child:
        socks = [connect(child.host, child.port) for _ in range(4)]
        plc = pyads.Connection(NET_ID, 851, f"{child.host}:{child.port}")
        plc.open()
        handle = plc.get_handle("GVL_Comp.cycle_count")
        last = [0]
        try:
            @settings(max_examples=500, deadline=None, database=None,
                      suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
            @given(st.lists(st.tuples(st.integers(0, 3), frames()), min_size=1, max_size=8))
            def fuzz(batch):
                for k, frame in batch:
                    socks[k].sendall(frame)
                    outcome = answered_or_closed(socks[k], frame)
                    tally["frames"] += 1
                    tally[outcome] += 1
                    if outcome == "answered" and frame[12:14] == (10000).to_bytes(2, "little"):
                        tally["answered by port 10000"] += 1
                    if outcome == "closed":
                        socks[k].close()
                        socks[k] = connect(child.host, child.port)
                count = plc.read_by_name("", pyads.PLCTYPE_UDINT, handle=handle)
                assert count >= last[0]
                last[0] = count
                tally["good reads"] += 1

            fuzz()
            for s in socks:                        # every port lent to a connection now closed was given back:
                s.close()                          # the lowest free one is lent again
            socks = []
            assert lowest_port_lent(child) == 30000
        finally:
            for s in socks:
                s.close()
            plc.release_handle(handle)
            plc.close()
    words = child.report["from_plc"]
    tally["PLC words written"] = sum(1 for w in words if w)
    print(f"ADS fuzz: {tally}")
    record_property("ads_fuzz_frames", tally["frames"])
    assert tally["frames"] >= 1000 and tally["answered"] > 0 and tally["closed"] > 0
    assert tally["answered by port 10000"] > 0 and tally["port lent"] > 0
    assert child.report["tampered"] == 0                 # nothing wrote into the service's block
    rmap = RegisterMap.from_yaml(MAP)
    start = rmap.blocks["from_plc"].start
    stray = [start + i for i, w in enumerate(words) if w and start + i not in rmap.writable]
    assert stray == []                                   # nor outside the PLC's registers
    assert log.stat().st_size < 100_000
