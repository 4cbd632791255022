"""Issue 30 in this process: the ``plc.writers`` and ``plc.tls`` settings, the exposure warning, the
rate-limited log of refused writes, certificate rotation, the ``none`` role, and `stiffcomp certs`.

The servers run in an I/O thread (`IoThread`, the same `IoServer` as the service's I/O process) with real
pymodbus clients; the running service is test_modbus_security.py's.
"""

from __future__ import annotations

import ipaddress
import json
import logging
import socket
import ssl
import struct
from pathlib import Path

import pytest
from cryptography import x509
from cryptography.hazmat.primitives.asymmetric import rsa
from hypothesis import given, settings
from hypothesis import strategies as st
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ConnectionException

from hil.testing import CONFIG, free_port, write_config
from io_base import certs
from io_base.errors import PlcError
from io_base.tls import role_of
from io_process.server import IoSettings, IoThread
from io_process.settings import MonitoringSettings
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from plc_link.settings import PlcSettings
from service.config import load_config
from service.errors import ServiceConfigError
from testlib.tls_certs import OUTSIDE, cert_set, outside_client, tls_client, tls_settings
from tools.cli import main

HB = 0x8001                 # plc_heartbeat, a register the PLC writes


class Served:
    """An `IoThread` serving ``plc`` with metrics (no HTTP), and its image."""

    def __init__(self, plc: PlcSettings):
        self.image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
        self.io = IoThread(self.image, IoSettings(plc=plc, monitoring=MonitoringSettings(enabled=False, metrics=True)))
        try:
            self.io.start()
        except BaseException:
            self.image.close()
            raise

    def count(self, kind: str, protocol: str, reason: str) -> float:
        labels = {"protocol": protocol, "reason": reason}
        return self.io.server.metrics.registry.get_sample_value(f"stiffcomp_{kind}_refused_total", labels) or 0.0

    def close(self) -> None:
        self.io.stop()
        self.image.close()


@pytest.fixture(scope="module")
def cs(tmp_path_factory):
    return cert_set(tmp_path_factory.mktemp("certs"))


@settings(max_examples=200, deadline=None)
@given(st.ip_addresses(v=4), st.integers(0, 32), st.ip_addresses(v=4))
def test_a_plain_client_may_write_exactly_when_its_address_is_in_a_writers_network(net, prefix, peer):
    network = ipaddress.ip_network(f"{net}/{prefix}", strict=False)
    s = PlcSettings(writers=[f"{net}/{prefix}"])
    assert s.writers == [str(network)]
    assert s.may_write(str(peer)) == (peer in network)
    assert s.may_write(f"::ffff:{peer}") == (peer in network)         # an IPv4-mapped peer of a dual-stack socket
    assert PlcSettings().may_write(str(peer))                         # no list: anyone, as before
    assert not PlcSettings(writers=[]).may_write(str(peer))           # an empty list: nobody


def test_config_errors_name_the_key(tmp_path):
    with pytest.raises(ServiceConfigError, match=r"plc\.writers.*300\.1\.2\.3"):
        load_config(write_config(tmp_path, {"plc": {"writers": ["300.1.2.3"]}}))
    with pytest.raises(ServiceConfigError, match=r"plc\.tls.*needs cert, key, ca.*stiffcomp certs"):
        load_config(write_config(tmp_path, {"plc": {"tls": {"enabled": True}}}))
    missing = str(tmp_path / "nowhere.pem")
    with pytest.raises(ServiceConfigError, match=r"(?s)file\(s\) it names not found.*plc\.tls\.cert = .*nowhere\.pem"):
        load_config(write_config(tmp_path, {"plc": {"tls": {"enabled": True, "cert": missing, "key": missing,
                                                           "ca": missing}}}))


def test_a_certificate_that_does_not_load_is_a_plc_error_naming_the_key(cs, tmp_path):
    bad = tmp_path / "bad.pem"
    bad.write_text("not a certificate\n")
    for key, tls in (("plc.tls.cert", {"cert": str(bad)}), ("plc.tls.ca", {"ca": str(bad)})):
        with pytest.raises(PlcError, match=key.replace(".", r"\.") + f" = {bad}"):
            Served(PlcSettings(port=free_port(), tls=tls_settings(cs, free_port(), **tls)))


@pytest.mark.parametrize("host, plc, warns", [
    ("127.0.0.1", {}, False), ("::1", {}, False), ("localhost", {}, False), ("127.0.0.5", {}, False),
    ("0.0.0.0", {}, True), ("", {}, True), ("192.168.10.5", {}, True), ("cell-ipc", {}, True),
    ("0.0.0.0", {"writers": ["192.168.10.20"]}, False), ("0.0.0.0", {"writers": []}, False),
    ("0.0.0.0", {"role": "client"}, False),
])
def test_the_exposure_warning_is_for_plain_writes_open_beyond_this_machine(host, plc, warns):
    w = PlcSettings(host=host, **plc).exposure_warning()
    assert (w is not None) == warns
    if warns:
        assert "plc.writers is not set" in w and f"{host}:5020" in w and "tare" in w


def test_tls_alone_beyond_this_machine_does_not_warn(cs):
    s = PlcSettings(host="0.0.0.0", tls=tls_settings(cs, 802, plain=False))
    assert s.exposure_warning() is None
    assert PlcSettings(host="0.0.0.0", tls=tls_settings(cs, 802)).exposure_warning() is not None   # plain beside


def test_a_server_bound_to_every_interface_without_writers_starts_with_one_warning(caplog):
    with caplog.at_level(logging.WARNING, logger="stiffcomp"):
        served = Served(PlcSettings(host="0.0.0.0", port=free_port()))
        served.close()
    lines = [r.getMessage() for r in caplog.records if "plc.writers" in r.getMessage()]
    assert len(lines) == 1 and "every host that reaches this port can write" in lines[0]


def test_refused_writes_are_counted_each_and_logged_once_with_their_source(caplog):
    served = Served(PlcSettings(port=free_port(), writers=["127.0.0.1"]))
    try:
        with caplog.at_level(logging.WARNING, logger="stiffcomp.modbus"), outside_client(served.io.server.settings.plc.port) as c:
            assert c.connect()
            for k in range(25):
                w = c.write_register(HB, k)
                assert w.isError() and w.exception_code == 0x01
            assert c.read_holding_registers(HB, count=1).registers == [0]
            # FC8 (diagnostics) can restart the communication: not a read, so not for a reader either
            r = c.diag_read_bus_message_count()
            assert r.isError() and r.exception_code == 0x01
        with ModbusTcpClient("127.0.0.1", port=served.io.server.settings.plc.port, timeout=3) as inside:
            assert not inside.write_register(HB, 99).isError()
        assert served.image.inputs().plc_heartbeat == 99
        assert served.count("requests", "modbus", "write not allowed") == 26
    finally:
        served.close()
    lines = [r.getMessage() for r in caplog.records if "write not allowed" in r.getMessage()]
    assert len(lines) == 1 and lines[0].startswith(f"{OUTSIDE}: Modbus TCP: write not allowed"), lines


def test_a_role_without_access_is_closed_after_the_handshake(cs):
    served = Served(PlcSettings(port=free_port(), tls=tls_settings(cs, free_port(), roles={"guest": "none"},
                                                                   default_access="write", plain=False)))
    try:
        port = served.io.server.settings.plc.tls.port
        c = tls_client(cs, port, cs.guest)
        try:
            with pytest.raises(ConnectionException):
                c.connect()
                c.read_holding_registers(HB, count=1)
        finally:
            c.close()
        with tls_client(cs, port, cs.norole) as c:                  # default_access: write
            assert c.connect() and not c.write_register(HB, 5).isError()
        assert served.count("connections", "modbus_tls", "certificate role without access") == 1
        with pytest.raises(ConnectionRefusedError):                 # TLS alone: no plain server
            socket.create_connection(("127.0.0.1", served.io.server.settings.plc.port), timeout=2).close()
    finally:
        served.close()


def read_frame(sock) -> bytes:
    """Read holding register HB over an established socket (MBAP, FC3); the answer's registers."""
    sock.sendall(struct.pack(">HHHBBHH", 1, 0, 6, 1, 3, HB, 1))
    return sock.recv(64)[9:]


def test_certificates_replaced_on_disk_serve_the_next_connection_without_a_restart(tmp_path, caplog):
    cs = cert_set(tmp_path / "certs")
    served = Served(PlcSettings(port=free_port(), tls=tls_settings(cs, free_port())))
    port = served.io.server.settings.plc.tls.port
    served.image.write("holding_registers", HB, [321])
    try:
        kept = tls_client(cs, port, cs.operator)
        assert kept.connect() and kept.read_holding_registers(HB, count=1).registers == [321]
        old = cs.ca.cert.read_bytes()
        with caplog.at_level(logging.INFO, logger="stiffcomp.modbus"):
            ca = certs.make_ca(cs.folder, "the cell's next CA", key_type="ec")      # rotation: a new CA, server
            certs.make_server(ca, cs.folder, ["localhost", "127.0.0.1"], key_type="ec")
            new = certs.make_client(ca, cs.folder, "next", "operator", key_type="ec")
            old_ca = tmp_path / "old_ca.pem"
            old_ca.write_bytes(old)
            # a client that trusts only the old CA no longer accepts the server; one of the new CA reads
            stale = tls_client(cs, port, cs.operator)
            stale.comm_params.sslctx = ssl.create_default_context(cafile=str(old_ca))
            stale.comm_params.sslctx.check_hostname = False
            stale.comm_params.sslctx.load_cert_chain(cs.operator.cert, cs.operator.key)
            assert not stale.connect()
            stale.close()
            with tls_client(cs, port, new) as c:                                   # cs.ca.cert: the new CA now
                assert c.connect() and not c.write_register(HB, 322).isError()
            assert kept.read_holding_registers(HB, count=1).registers == [322]      # an open session goes on
            kept.close()
            # a name-checking client (server_hostname) accepts the server certificate's names
            ctx = ssl.create_default_context(cafile=str(cs.ca.cert))
            ctx.load_cert_chain(new.cert, new.key)
            with socket.create_connection(("127.0.0.1", port), timeout=3) as raw, \
                    ctx.wrap_socket(raw, server_hostname="localhost") as s:
                assert read_frame(s) == struct.pack(">H", 322)
            cs.server.cert.write_text("half a file\n")                               # a rotation gone wrong
            with tls_client(cs, port, new) as c:
                assert c.connect() and c.read_holding_registers(HB, count=1).registers == [322]
    finally:
        served.close()
    messages = [r.getMessage() for r in caplog.records]
    assert sum("new certificates loaded" in m for m in messages) == 1
    assert any("do not load; new connections keep the previous certificates" in m and "plc.tls.cert" in m
               for m in messages)


@settings(max_examples=8, deadline=None)
@given(st.text(min_size=1, max_size=40).filter(lambda t: "\x00" not in t))
def test_the_role_in_a_certificate_round_trips(tmp_path_factory, role):
    folder = tmp_path_factory.mktemp("role")
    ca = certs.make_ca(folder, key_type="ec")
    issued = certs.make_client(ca, folder, "c", role, key_type="ec")
    assert role_of(ssl.PEM_cert_to_DER_cert(issued.cert.read_text())) == role


def test_certs_makes_a_ca_once_a_server_and_clients_with_their_roles(tmp_path, capsys):
    folder = tmp_path / "cell"
    assert main(["certs", str(folder), "--client", "plc:operator", "--client", "hmi:viewer", "--json"]) == 0
    made = json.loads(capsys.readouterr().out)
    assert made["ca"]["new"] and {c["name"]: c["role"] for c in made["clients"]} == {"plc": "operator", "hmi": "viewer"}
    assert made["config"]["plc"]["tls"]["ca"] == "cell/ca.pem" and "next" in made      # beside a config in tmp_path
    for name in ("ca", "server", "plc", "hmi"):
        assert (folder / f"{name}.key").stat().st_mode & 0o777 == 0o600
        key = x509.load_pem_x509_certificate((folder / f"{name}.pem").read_bytes()).public_key()
        assert isinstance(key, rsa.RSAPublicKey) and key.key_size == 2048        # the protocol's RSA suites
    ca = x509.load_pem_x509_certificate((folder / "ca.pem").read_bytes())
    server = (folder / "server.pem").read_bytes()
    assert role_of(ssl.PEM_cert_to_DER_cert((folder / "hmi.pem").read_text())) == "viewer"
    assert main(["certs", str(folder), "--client", "late", "--key-type", "ec"]) == 0
    assert (folder / "server.pem").read_bytes() == server                       # kept: no --host
    late = x509.load_pem_x509_certificate((folder / "late.pem").read_bytes())
    late.verify_directly_issued_by(ca)                                          # the same CA signs later clients
    assert role_of(ssl.PEM_cert_to_DER_cert((folder / "late.pem").read_text())) == "operator"
    assert "plc:\n  tls:\n    enabled: true" in capsys.readouterr().out
    (folder / "ca.key").unlink()
    assert main(["certs", str(folder), "--client", "x"]) == 2
    assert "ca.key is missing" in capsys.readouterr().err
    assert not Path(folder / "x.pem").exists()


def test_garbage_on_the_tls_port_closes_that_connection_only(cs, caplog):
    """Random bytes, some of them starting like a TLS record, then a PLC with its certificate is served;
    nothing but the rate-limited refusals is logged (no task exception, no traceback)."""
    served = Served(PlcSettings(port=free_port(), tls=tls_settings(cs, free_port())))
    port = served.io.server.settings.plc.tls.port
    plc = tls_client(cs, port, cs.operator)

    @settings(max_examples=40, deadline=None, database=None)
    @given(st.one_of(st.binary(max_size=300), st.binary(max_size=300).map(lambda b: b"\x16\x03\x01" + b)))
    def garbage(data):
        with socket.create_connection(("127.0.0.1", port), timeout=3) as s:
            s.sendall(data)
            s.shutdown(socket.SHUT_WR)
            try:
                while s.recv(4096):
                    pass
            except OSError:
                pass
        assert not plc.write_register(HB, len(data)).isError()

    try:
        with caplog.at_level(logging.WARNING):
            assert plc.connect()
            garbage()
        assert served.count("connections", "modbus_tls", "not TLS") + \
            served.count("connections", "modbus_tls", "TLS handshake failed") + \
            served.count("connections", "modbus_tls", "closed during the TLS handshake") >= 1
    finally:
        plc.close()
        served.close()
    assert [r for r in caplog.records if r.levelno >= logging.ERROR or r.exc_info] == []


def test_status_reads_over_ads_when_modbus_is_tls_alone(cs, tmp_path, capsys):
    from service.config import read_sections
    from tools.status_cmd import reader_for

    alone = read_sections(write_config(tmp_path, {"plc": {"tls": tls_settings(cs, 802, plain=False)}}), "plc", "ads")
    assert reader_for(alone, "auto", None, None)[1] == "ads"
    beside = read_sections(write_config(tmp_path, {"plc": {"tls": tls_settings(cs, 802)}}), "plc", "ads")
    assert reader_for(beside, "auto", None, None)[1] == "modbus"
    neither = write_config(tmp_path, {"plc": {"tls": tls_settings(cs, 802, plain=False)}, "ads": {"enabled": False}})
    assert main(["status", "--config", str(neither)]) == 2
    assert "plc.role is server with TLS alone and ads.enabled is false" in capsys.readouterr().err
