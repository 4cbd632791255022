"""Random and mutated Modbus and AMS/TCP frames against the running service (hypothesis).

The service runs as deployed (the cycle here, Modbus and ADS in the I/O process). Frames come from
several connections to both ports; after every example a well-behaved Modbus client and a pyads
client are still served. Over the whole fuzz the cycle raises no overrun and no sensor fault (the
I/O cannot disturb its timing), no word outside the PLC's registers is ever written, and the log stays
under 100 kB. Faults that the PLC's own values cause (a fuzzed q outside the joint limits) are the
contract working, not a disturbance, and are allowed.
"""

from __future__ import annotations

import socket
import struct

import pyads
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient
from test_ads_fuzz import frames as ams_frames

from hil.testing import free_port, write_config
from service.app import Service
from service.config import load_config

pytestmark = pytest.mark.realtime

CYCLES = "TwinCAT_SystemInfoVarList._TaskInfo[1].CycleCount"


@st.composite
def modbus_frames(draw) -> bytes:
    """An MBAP frame with a PDU of any function code, often near the map's blocks, sometimes mutated."""
    fc = draw(st.sampled_from([1, 2, 3, 4, 5, 6, 15, 16, 23, 0x2B, 0x80, 0]))
    address = draw(st.one_of(st.integers(0x7FF0, 0x8110), st.integers(0, 0xFFFF)))
    count = draw(st.one_of(st.integers(0, 130), st.integers(0, 0xFFFF)))
    if fc in (15, 16):
        data = draw(st.binary(max_size=40))
        pdu = struct.pack(">BHHB", fc, address, count, len(data)) + data
    elif fc == 23:
        data = draw(st.binary(max_size=20))
        pdu = struct.pack(">BHHHHB", fc, address, count, address, len(data) // 2, len(data)) + data
    else:
        pdu = struct.pack(">BHH", fc, address, count)
    length = draw(st.one_of(st.just(len(pdu) + 1), st.integers(0, 300)))
    frame = struct.pack(">HHHB", draw(st.integers(0, 0xFFFF)), draw(st.sampled_from([0, 0, 1])), length,
                        draw(st.integers(0, 255))) + pdu
    how = draw(st.sampled_from(["as is", "as is", "flip", "cut", "random"]))
    if how == "flip":
        b = bytearray(frame)
        b[draw(st.integers(0, len(b) - 1))] = draw(st.integers(0, 255))
        frame = bytes(b)
    elif how == "cut":
        frame = frame[: draw(st.integers(0, len(frame) - 1))]
    elif how == "random":
        frame = draw(st.binary(max_size=64))
    return frame


def blast(port: int, batch: list[bytes]) -> int:
    """Send each frame on one of up to 4 connections; read what comes back (the server may close);
    returns how many were sent."""
    conns: list[socket.socket] = []
    sent = 0
    try:
        for k, frame in enumerate(batch):
            if len(conns) <= k % 4:
                conns.append(socket.create_connection(("127.0.0.1", port), timeout=1.0))
            c = conns[k % 4]
            try:
                c.sendall(frame)
            except OSError:
                continue
            sent += 1
        for c in conns:
            c.settimeout(0.01)
            try:
                while c.recv(4096):
                    pass
            except OSError:
                pass
    finally:
        for c in conns:
            c.close()
    return sent


def test_fuzz_against_the_running_service(tmp_path, capfd, record_property):
    modbus_port, ads_port = free_port(), free_port()
    # SCHED_FIFO for the cycle, as a deployment runs it (docs/deploy.md); without the permission the
    # service warns and runs at normal priority
    cfg = load_config(write_config(tmp_path, {"plc": {"port": modbus_port}, "ads": {"port": ads_port},
                                              "cycle": {"realtime_priority": 50}}))
    service = Service(cfg)
    service.start()
    codec = service.rmap.codecs["to_plc"]
    sent = 0

    @settings(max_examples=80, deadline=None, suppress_health_check=list(HealthCheck), database=None)
    @given(st.lists(modbus_frames(), min_size=10, max_size=60), st.lists(ams_frames(), min_size=10, max_size=60))
    def fuzz(modbus_batch, ams_batch):
        nonlocal sent
        sent += blast(modbus_port, modbus_batch) + blast(ads_port, ams_batch)
        assert not mb.read_input_registers(codec.start, count=codec.words).isError()      # a well-behaved PLC
        assert plc.read_by_name(CYCLES, pyads.PLCTYPE_UDINT) > 0                         # a TwinCAT script

    mb = ModbusTcpClient("127.0.0.1", port=modbus_port, timeout=2)
    plc = pyads.Connection("127.0.0.1.1.1", 851, f"127.0.0.1:{ads_port}")
    try:
        assert mb.connect()
        plc.open()
        fuzz()
        trips = dict(service.cycle.faults.trips)
        rmap = service.rmap
        b = rmap.blocks["from_plc"]
        with ModbusTcpClient("127.0.0.1", port=modbus_port, timeout=2) as c:
            assert c.connect()
            words = []
            for start in range(b.start, b.start + b.size, 125):
                words += c.read_holding_registers(start, count=min(125, b.start + b.size - start)).registers
    finally:
        mb.close()
        plc.close()
        service.stop()
    assert trips["overrun"] == 0, "the cycle overran while the I/O process was fuzzed"
    assert all(trips[k] == 0 for k in ("sensor_timeout", "sensor_status", "sensor_saturated", "can_frame")), trips
    stray = [hex(b.start + k) for k, w in enumerate(words) if w and b.start + k not in rmap.writable]
    assert stray == []
    log = capfd.readouterr()
    assert len(log.out) + len(log.err) < 100_000
    record_property("fuzz_frames", sent)
    print(f"fuzz: {sent} Modbus and AMS frames sent to the running service; faults tripped: "
          f"{ {k: v for k, v in trips.items() if v} }")
    assert sent > 2000
