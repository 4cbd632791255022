"""`stiffcomp run --check` checks the addresses the I/O process's own settings declare (issue 51, item 5): for
any config, the listeners the check reads (without the model) are the sockets a started I/O server binds, no
more and no fewer, and in the order it starts them."""

from __future__ import annotations

import socket
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.testing import free_port, sockets_open, write_config
from io_process.server import IoThread
from plc_link.image import ProcessImage
from service.compensation import load_model
from service.config import load_config
from service.io_config import io_listeners, io_settings
from service.preflight import check_start
from testlib.tls_certs import cert_set, tls_settings

pytestmark = pytest.mark.realtime

CONFIGS = st.fixed_dictionaries({
    "role": st.sampled_from(["server", "client", "none"]),
    "tls": st.sampled_from(["off", "beside plain", "alone"]),
    "ads": st.booleans(),
    "monitoring": st.booleans(),
    "robot": st.sampled_from(["none", "kuka_rsi", "abb_egm"]),
})
STATES = {"tcp": "0A", "tcp6": "0A", "udp": "07", "udp6": "07"}     # LISTEN; a UDP socket bound, not connected


def listening(inodes: set[str]) -> set[tuple[str, int, str]]:
    """(host, port, transport) of every socket of ``inodes`` that listens: TCP in LISTEN, UDP bound (Linux
    /proc/net, IPv4 and IPv6)."""
    out = set()
    for table, state in STATES.items():
        family = socket.AF_INET6 if table.endswith("6") else socket.AF_INET
        for line in Path(f"/proc/net/{table}").read_text().splitlines()[1:]:
            fields = line.split()
            if fields[3] != state or fields[9] not in inodes:
                continue
            address, port = fields[1].split(":")
            raw = bytes.fromhex(address)
            raw = b"".join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))     # each 32-bit word little-endian
            out.add((socket.inet_ntop(family, raw), int(port, 16), table.rstrip("6")))
    return out


def socket_inodes() -> set[str]:
    """The inodes of the sockets this process holds."""
    return {target[len("socket:["):-1] for target in sockets_open()}


def overrides(case: dict, certs) -> dict:
    """The config's sections for ``case``, each server on a port of its own."""
    ports: set[int] = set()

    def port(kind=socket.SOCK_STREAM) -> int:
        while (p := free_port(kind)) in ports:
            pass
        ports.add(p)
        return p

    tls = {"enabled": False} if case["tls"] == "off" else tls_settings(certs, port(), plain=case["tls"] != "alone")
    robot = {"interface": "none"}
    if case["robot"] != "none":
        robot = {"interface": case["robot"], "host": "127.0.0.1", "port": port(socket.SOCK_DGRAM), case["robot"]: {}}
    return {"plc": {"role": case["role"], "host": "127.0.0.1", "port": port(), "tls": tls,
                    "client": {"timeout_s": 0.2}},
            "ads": {"enabled": case["ads"], "host": "127.0.0.1", "port": port()},
            "monitoring": {"enabled": case["monitoring"], "host": "127.0.0.1", "port": port()}, "robot": robot}


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return tmp_path_factory.mktemp("listeners")


@pytest.fixture(scope="module")
def certs(folder):
    return cert_set(folder / "certs")


@pytest.fixture(scope="module")
def robot(folder):
    """The model's robot (the road's limits), loaded once: the config's model is the same in every case."""
    return load_model(load_config(write_config(folder, {}, name="model.yaml"))).robot


@settings(max_examples=40, deadline=None)
@given(case=CONFIGS)
def test_the_checked_listeners_are_what_the_io_server_binds(case, folder, certs, robot):
    cfg = load_config(write_config(folder, overrides(case, certs)))
    declared = io_listeners(cfg)
    checked = check_start(cfg).checked
    assert checked == [f"{key} {host}:{port}/{transport} free" for key, host, port, transport in declared]
    settings = io_settings(cfg, robot)
    if settings is None:                        # nothing to serve: no I/O process
        assert declared == []
        return
    assert settings.listeners() == declared
    with socket.socket() as plc:                # the PLC a client connects to (the kernel accepts for it)
        if case["role"] == "client":
            plc.bind((cfg.plc.host, cfg.plc.port))
            plc.listen()
        before = socket_inodes()
        image = ProcessImage(cfg.register_map())
        io = IoThread(image, settings)
        try:
            io.start()
            bound = listening(socket_inodes() - before)
            started = [type(part).__name__ for part in io.server.parts]
        finally:
            io.stop()
            image.close()
    assert bound == {(host, port, transport) for _, host, port, transport in declared}
    assert len(bound) == len(declared)
    server = {"plc.port": "ModbusServer", "plc.tls.port": "ModbusServer", "robot.port": "RobotRoad",
              "ads.port": "_Ads", "monitoring.port": "Monitor"}
    assert [p for p in started if p != "ModbusClient"] == [server[key] for key, *_ in declared]
