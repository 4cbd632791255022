"""Issue 30 against the running service: who may write over Modbus, Modbus/TCP Security, and mbpoll.

One service for the whole module, as deployed (`stiffcomp run` in a child process), with plain Modbus
TCP (``plc.writers``: 127.0.0.1 only) beside Modbus/TCP Security (mutual TLS, roles) and the metrics
endpoint. What the PLC has written is read back as the holding registers, by a client that may write. Clients are real: pymodbus' TCP client from a second loopback address (127.0.0.2, not a
writer), pymodbus' TLS client with the cell's certificates, none, or another CA's, and mbpoll (libmodbus).
"""

from __future__ import annotations

import shutil
import subprocess

import pytest
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ConnectionException

from hil.run import ServiceProcess
from hil.testing import free_port, write_config
from plc_link.contract import TaskState
from service.config import load_config
from testlib.metrics import scrape
from testlib.tls_certs import OUTSIDE, cert_set, outside_client, tls_client, tls_settings

pytestmark = pytest.mark.realtime

NOT_ALLOWED = 0x01          # Modbus/TCP Security's answer to an unauthorized request: illegal function
MBPOLL = shutil.which("mbpoll")


class Running:
    """The service, its certificates, and a plain client from 127.0.0.1 (a writer)."""

    def __init__(self, folder):
        self.certs = cert_set(folder / "certs")
        self.port, self.tls_port = free_port(), free_port()
        path = write_config(folder, {
            "plc": {"port": self.port, "writers": ["127.0.0.1/32"], "tls": tls_settings(self.certs, self.tls_port)},
            "monitoring": {"metrics": True}, "cycle": {"realtime_priority": 0}})
        self.cfg = load_config(path)
        self.rmap = self.cfg.register_map()
        self.proc = ServiceProcess(path, folder)
        self.proc.wait_running(60)
        self.plc = ModbusTcpClient("127.0.0.1", port=self.port, timeout=3)
        assert self.plc.connect()

    def address(self, name: str) -> int:
        return self.rmap.by_name[name].address

    def from_plc(self) -> dict[str, float]:
        """What the PLC has written, by name (the holding registers, as a writer reads them)."""
        codec = self.rmap.codecs["from_plc"]
        r = self.plc.read_holding_registers(codec.start, count=codec.words)
        assert not r.isError(), r
        return dict(zip(codec.names, codec.decode(r.registers)))

    def to_plc(self, client=None) -> dict[str, float]:
        codec = self.rmap.codecs["to_plc"]
        r = (client or self.plc).read_input_registers(codec.start, count=codec.words)
        assert not r.isError(), r
        return dict(zip(codec.names, codec.decode(r.registers)))

    def refused(self, kind: str, protocol: str, reason: str) -> float:
        """A refusal counter of the metrics endpoint: ``kind`` requests or connections."""
        labels = (("protocol", protocol), ("reason", reason))
        return scrape(self.cfg.monitoring.port).get((f"stiffcomp_{kind}_refused_total", labels), 0.0)

    def log(self) -> str:
        return self.proc.log_path.read_text()

    def close(self) -> None:
        self.plc.close()
        self.proc.stop()


@pytest.fixture(scope="module")
def svc(tmp_path_factory):
    s = Running(tmp_path_factory.mktemp("security"))
    try:
        yield s
    finally:
        s.close()


def test_a_write_from_outside_the_writers_changes_nothing_and_gets_exception_01(svc):
    hb, command = svc.address("plc_heartbeat"), svc.address("command_word")
    assert not svc.plc.write_register(hb, 1234).isError()           # a writer (127.0.0.1) writes
    before = svc.from_plc()
    assert before["plc_heartbeat"] == 1234
    counted = svc.refused("requests", "modbus", "write not allowed")
    with outside_client(svc.port) as c:
        assert c.connect()
        assert c.socket.getsockname()[0] == OUTSIDE
        assert svc.to_plc(c)["task_state"] == TaskState.RUN             # reading is everyone's
        writes = [c.write_register(command, 0b011),                    # enable and tare, FC6
                  c.write_registers(hb, [4321]),                       # FC16
                  c.readwrite_registers(read_address=hb, read_count=1, address=hb, values=[4321]),  # FC23
                  c.mask_write_register(address=command, and_mask=0, or_mask=0b100)]        # FC22
        assert [(w.isError(), getattr(w, "exception_code", None)) for w in writes] == [(True, NOT_ALLOWED)] * 4
        r = c.read_holding_registers(hb, count=1)
        assert not r.isError() and r.registers == [1234]
    assert svc.from_plc() == before
    assert svc.refused("requests", "modbus", "write not allowed") == counted + 4
    assert f"{OUTSIDE}: Modbus TCP: write not allowed (address not in plc.writers)" in svc.log()
    assert "plc.writers is not set" not in svc.log()                 # loopback: no exposure warning


def test_a_tls_client_with_the_cells_certificate_reads_and_writes(svc):
    hb = svc.address("plc_heartbeat")
    with tls_client(svc.certs, svc.tls_port, svc.certs.operator) as c:
        assert c.connect()
        assert svc.to_plc(c)["cycle_count"] > 0
        for value in (555, 556):
            assert not c.write_register(hb, value).isError()
            assert svc.from_plc()["plc_heartbeat"] == value
            assert c.read_holding_registers(hb, count=1).registers == [value]


def test_a_reader_role_reads_but_may_not_write(svc):
    hb = svc.address("plc_heartbeat")
    counted = svc.refused("requests", "modbus_tls", "write not allowed")
    for cert in (svc.certs.viewer, svc.certs.norole, svc.certs.guest):   # viewer; no role, unlisted: default_access
        before = svc.from_plc()
        with tls_client(svc.certs, svc.tls_port, cert) as c:
            assert c.connect()
            assert svc.to_plc(c)["cycle_count"] > 0
            w = c.write_register(hb, int(before["plc_heartbeat"]) + 1)
            assert w.isError() and w.exception_code == NOT_ALLOWED
        assert svc.from_plc() == before
    assert svc.refused("requests", "modbus_tls", "write not allowed") == counted + 3
    assert "Modbus/TCP Security: write not allowed (certificate role 'viewer' may read)" in svc.log()


@pytest.mark.parametrize("who, reason", [("none", "no client certificate"),
                                         ("foreign", "client certificate not trusted")])
@pytest.mark.parametrize("tls12", [False, True], ids=["tls1.3", "tls1.2"])
def test_a_tls_client_without_a_valid_certificate_is_refused_at_the_handshake(svc, who, reason, tls12):
    """At most TLS 1.2, the client's connect fails. In TLS 1.3 the client's side of the handshake ends
    before the server has checked its certificate: the server's refusal then closes the connection
    before any request is answered."""
    counted = svc.refused("connections", "modbus_tls", reason)
    before = svc.from_plc()
    c = tls_client(svc.certs, svc.tls_port, None if who == "none" else svc.certs.foreign, tls12)
    try:
        if tls12:
            assert not c.connect()
        else:
            assert c.connect()
            with pytest.raises(ConnectionException):
                c.write_register(svc.address("plc_heartbeat"), int(before["plc_heartbeat"]) + 7)
    finally:
        c.close()
    assert svc.from_plc() == before
    assert svc.refused("connections", "modbus_tls", reason) == counted + 1
    assert svc.log().count(f"127.0.0.1: Modbus/TCP Security: {reason} (closed): 1 time(s), first report") == 1


def mbpoll(port: int, kind: str, address: int, *values, count: int = 1) -> list[float]:
    """mbpoll once at the PDU ``address`` (-0): reads ``count`` values of ``kind`` (3: input, 4: holding
    registers; ``:float`` two words, low word first, mbpoll's default), or writes ``values``."""
    cmd = [MBPOLL, "-m", "tcp", "-p", str(port), "-a", "1", "-0", "-1", "-t", kind, "-r", str(address)]
    cmd += ["-c", str(count), "127.0.0.1"] if not values else ["127.0.0.1", "--", *map(str, values)]
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=30, check=False)
    assert p.returncode == 0, p.stdout + p.stderr
    # "[32768]: \t42448 (-23088)": a 16-bit word prints as unsigned, then signed
    return [float(line.split(":", 1)[1].split()[0]) for line in p.stdout.splitlines() if line.startswith("[")]


@pytest.mark.skipif(MBPOLL is None, reason="mbpoll (libmodbus) is not installed: `make test` installs the "
                                           "Debian package mbpoll where it runs as root with apt-get")
def test_mbpoll_agrees_with_the_register_map(svc):
    """libmodbus from an allowed address, by address: pymodbus reads its writes back by name through the
    map, and its reads decode, through the map, to what the cycle publishes."""
    q = [12.5, -80.25, 95.0, 3.0, 44.0, -7.5]
    mbpoll(svc.port, "4:float", svc.address("q1"), *q)
    mbpoll(svc.port, "4", svc.address("plc_heartbeat"), 777)
    got = svc.from_plc()
    assert [got[f"q{i}"] for i in range(1, 7)] == q and got["plc_heartbeat"] == 777
    assert mbpoll(svc.port, "4:float", svc.address("q1"), count=6) == q
    codec = svc.rmap.codecs["to_plc"]
    first = svc.to_plc()["cycle_count"]
    values = dict(zip(codec.names, codec.decode([int(w) for w in mbpoll(svc.port, "3", codec.start,
                                                                        count=codec.words)])))
    assert values["task_state"] == TaskState.RUN
    assert values["cycle_time_us"] == svc.cfg.cycle.period_ms * 1000.0
    assert first <= values["cycle_count"] <= svc.to_plc()["cycle_count"]
    assert mbpoll(svc.port, "3:float", svc.address("cycle_time_us")) == [values["cycle_time_us"]]
