"""Issue 17, item 5: clients cannot lock others out, on ADS and Modbus alike (io_base.client_table).

The table's policy with a clock of the test's own; then the servers in an I/O thread of this process
(silent and idle connections are closed, one with notifications is not); then the running service
(`stiffcomp run`): with 100 idle TCP connections to each of the ADS and Modbus ports, a pyads read and
a Modbus read answer within 2 s, and a PLC polling both throughout keeps its connections.
"""

from __future__ import annotations

import socket
import struct
import threading
import time

import pyads
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient

from hil.run import ServiceProcess
from hil.testing import CONFIG, free_port, write_config
from io_base.client_table import POLLING_S, ClientTable
from io_base.settings import ClientLimits
from io_process.server import IoSettings, IoThread
from plc_link.ads import AdsSettings, ams
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from plc_link.settings import PlcSettings
from testlib.ads_child import recv_exact

pytestmark = pytest.mark.realtime

NET_ID = "127.0.0.1.1.1"


class Clock:
    def __init__(self):
        self.t = 1000.0

    def __call__(self) -> float:
        return self.t


def table(max_clients=3, first=10.0, idle=60.0):
    clock, closed = Clock(), []
    t = ClientTable(ClientLimits(max_clients=max_clients, first_frame_timeout_s=first, idle_timeout_s=idle),
                    lambda c, reason: closed.append((c.peer, reason)), clock)
    return t, clock, closed


def test_the_longest_idle_gives_way_never_a_polling_client():
    t, clock, closed = table()
    plc = t.add("plc", lambda: None)
    t.request(plc)
    clock.t += 5
    t.add("silent", lambda: None)                     # never sends a request
    watcher = t.add("watcher", lambda: None, busy=lambda: True)
    t.request(watcher)
    clock.t += 5
    t.request(plc)                                     # the PLC polls
    assert t.add("new1", lambda: None) is not None     # full: the one that never sent a request goes first
    assert closed == [("silent", "gave way to a new client (max_clients reached)")]
    t.request(next(c for c in t.clients if c.peer == "new1"))
    clock.t += POLLING_S                               # the PLC polls again; new1 is idle now, watcher busy
    t.request(plc)
    assert t.add("new2", lambda: None) is not None
    assert closed[-1][0] == "new1"
    t.request(next(c for c in t.clients if c.peer == "new2"))
    t.request(watcher)
    clock.t += 0.5 * POLLING_S
    t.request(plc)
    assert t.add("new3", lambda: None) is None         # everyone polled within the last second: refused
    assert {c.peer for c in t.clients} == {"plc", "watcher", "new2"}


def test_sweep_closes_silent_and_idle_clients_but_not_busy_ones():
    t, clock, closed = table(max_clients=10, first=2.0, idle=30.0)
    silent = t.add("silent", lambda: None)
    talker = t.add("talker", lambda: None)
    watcher = t.add("watcher", lambda: None, busy=lambda: True)
    t.request(talker)
    t.request(watcher)
    clock.t += 2.5
    t.sweep()
    assert closed == [("silent", "no request within first_frame_timeout_s (closed)")] and silent not in t.clients
    clock.t += 30.0
    t.sweep()
    assert closed[-1] == ("talker", "idle beyond idle_timeout_s (closed)")
    assert [c.peer for c in t.clients] == ["watcher"]


@settings(max_examples=200, deadline=None)
@given(st.integers(1, 6), st.lists(st.tuples(st.sampled_from(["add", "request", "tick", "sweep", "leave"]),
                                              st.integers(0, 20), st.floats(0.0, 3.0)), max_size=60))
def test_the_table_never_overflows_and_never_evicts_a_polling_client(max_clients, events):
    t, clock, closed = table(max_clients=max_clients, first=5.0, idle=20.0)
    last_request: dict[str, float] = {}
    for n, (what, k, dt) in enumerate(events):
        if what == "add":
            before = len(closed)
            c = t.add(f"c{n}", lambda: None)
            for peer, reason in closed[before:]:
                assert "gave way" in reason
                assert peer not in last_request or clock.t - last_request[peer] >= POLLING_S
            if c is None:
                assert all(clock.t - last_request.get(x.peer, -1e9) < POLLING_S for x in t.clients)
        elif what == "request" and t.clients:
            c = t.clients[k % len(t.clients)]
            t.request(c)
            last_request[c.peer] = clock.t
        elif what == "tick":
            clock.t += dt
        elif what == "sweep":
            t.sweep()
        elif what == "leave" and t.clients:
            t.remove(t.clients[k % len(t.clients)])
        assert len(t.clients) <= max_clients


# -- the servers, in an I/O thread of this process -----------------------------------------------------
def modbus_read(tid: int) -> bytes:
    """FC4, two input registers at 0x8000 (heartbeat, status_word)."""
    return struct.pack(">HHHBBHH", tid, 0, 6, 1, 4, 0x8000, 2)


def ads_read_state(invoke: int) -> bytes:
    return ams.request_frame(ams.net_id_bytes(NET_ID), 851, ams.net_id_bytes("127.0.0.1.1.9"), 30001,
                             ams.READ_STATE, b"", invoke)


def answered(s: socket.socket, frame: bytes, size: int) -> bool:
    """Whether ``frame`` gets a ``size``-byte answer on ``s`` (False: the server closed it)."""
    try:
        s.sendall(frame)
        return recv_exact(s, size) is not None
    except OSError:
        return False


def closed_by_server(s: socket.socket, deadline_s: float = 30.0) -> bool:
    s.settimeout(deadline_s)
    try:
        return s.recv(1) == b""
    except TimeoutError:
        return False
    except OSError:
        return True


@pytest.fixture
def io_servers():
    image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    limits = {"first_frame_timeout_s": 0.3, "idle_timeout_s": 0.6}
    mb, ads = free_port(), free_port()
    io = IoThread(image, IoSettings(plc=PlcSettings(port=mb, **limits), ads=AdsSettings(port=ads, **limits)))
    io.start()
    try:
        yield mb, ads
    finally:
        io.stop()
        image.close()


def test_silent_and_idle_connections_are_closed_one_with_notifications_is_not(io_servers):
    mb, ads = io_servers
    socks = {name: socket.create_connection(("127.0.0.1", port), timeout=10)
             for name, port in (("mb silent", mb), ("mb idle", mb), ("ads silent", ads), ("ads idle", ads),
                                ("ads watcher", ads))}
    try:
        assert answered(socks["mb idle"], modbus_read(1), 13)
        assert answered(socks["ads idle"], ads_read_state(1), 46)
        add = struct.pack("<IIIIII16x", 0x4040, 4, 4, ams.TRANS_SERVER_CYCLE, 0, 10_000_000)    # every 1 s
        assert answered(socks["ads watcher"], ams.request_frame(
            ams.net_id_bytes(NET_ID), 851, ams.net_id_bytes("127.0.0.1.1.9"), 30001, ams.ADD_NOTIFICATION, add, 2),
            6 + 32 + 8)
        for name in ("mb silent", "mb idle", "ads silent", "ads idle"):
            assert closed_by_server(socks[name]), name
        # the idle ones are gone; the one holding a notification is still served
        assert answered(socks["ads watcher"], ads_read_state(3), 46) or \
            answered(socks["ads watcher"], ads_read_state(4), 46)      # a notification may come first
    finally:
        for s in socks.values():
            s.close()


# -- the running service -------------------------------------------------------------------------------
def test_100_idle_connections_to_each_port_lock_out_neither_pyads_nor_modbus(tmp_path, record_property):
    mb, ads = free_port(), free_port()
    service = ServiceProcess(write_config(tmp_path, {"plc": {"port": mb}, "ads": {"port": ads}}), tmp_path)
    idle: list[socket.socket] = []
    polls = {"modbus": 0, "ads": 0, "lost": []}
    stop = threading.Event()

    def plc():                          # the PLC: polls both ports every few ms on one connection each
        m = socket.create_connection(("127.0.0.1", mb), timeout=10)
        a = socket.create_connection(("127.0.0.1", ads), timeout=10)
        try:
            n = 0
            while not stop.is_set():
                n += 1
                for key, s, frame, size in (("modbus", m, modbus_read(n & 0xFFFF), 13),
                                            ("ads", a, ads_read_state(n), 46)):
                    if answered(s, frame, size):
                        polls[key] += 1
                    else:
                        polls["lost"].append(key)
                        return
                stop.wait(0.005)
        finally:
            m.close()
            a.close()

    poller = threading.Thread(target=plc)
    try:
        service.wait_running()
        poller.start()
        give_up = time.monotonic() + 30.0          # a guard against a hang: the PLC polls before the flood
        while min(polls["modbus"], polls["ads"]) < 3 and not polls["lost"] and time.monotonic() < give_up:
            time.sleep(0.01)
        for port in (ads, mb):
            idle += [socket.create_connection(("127.0.0.1", port), timeout=10) for _ in range(100)]
        t0 = time.monotonic()
        plc_ads = pyads.Connection(NET_ID, 851, f"127.0.0.1:{ads}")
        plc_ads.open()
        try:
            count = plc_ads.read_by_name("TwinCAT_SystemInfoVarList._TaskInfo[1].CycleCount")
        finally:
            plc_ads.close()
        ads_s = time.monotonic() - t0
        t0 = time.monotonic()
        with ModbusTcpClient("127.0.0.1", port=mb, timeout=2, retries=0) as c:
            assert c.connect()
            r = c.read_input_registers(0x8004, count=2)
        modbus_s = time.monotonic() - t0
        stop.set()
        poller.join(30)
    finally:
        stop.set()
        for s in idle:
            s.close()
        service.stop()
    record_property("seconds to answer (pyads, modbus)", (round(ads_s, 3), round(modbus_s, 3)))
    print(f"with 100 idle connections on each port: pyads read {ads_s:.3f} s, Modbus read {modbus_s:.3f} s; "
          f"the PLC polled {polls['modbus']} times on each")
    assert count > 0 and not r.isError()
    assert ads_s < 2.0 and modbus_s < 2.0, (ads_s, modbus_s)
    assert polls["lost"] == [] and polls["modbus"] > 0 and polls["ads"] > 0, polls
    assert service.proc.returncode == 0
