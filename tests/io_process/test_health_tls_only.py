"""`stiffcomp health` against a running service that serves Modbus/TCP Security alone and no HTTP
(``plc.tls.enabled: true``, ``plain: false``, ``monitoring.enabled: false``): the probe asks by what the
config serves, Modbus/TCP Security with the client certificate ``plc.tls.probe_cert`` names, else ADS,
or exits 2 saying why it cannot; it never asks the plain port nothing serves. The start-up line names
what listens.
"""

from __future__ import annotations

import socket
from typing import Self

import pytest
import yaml

from hil.run import ServiceProcess
from hil.testing import free_port, write_config
from testlib.common import wait_for
from testlib.tls_certs import cert_set, tls_settings
from tools.cli import main

pytestmark = pytest.mark.realtime


class TlsOnly:
    """The service with TLS alone, HTTP off and ADS on, its certificates (the probe shows ``viewer``'s)."""

    def __init__(self, folder):
        self.folder = folder
        self.certs = cert_set(folder / "certs")
        self.port, self.tls_port, self.ads_port = free_port(), free_port(), free_port()
        probe = {"probe_cert": str(self.certs.viewer.cert), "probe_key": str(self.certs.viewer.key)}
        self.config = write_config(folder, {
            "plc": {"port": self.port, "tls": tls_settings(self.certs, self.tls_port, plain=False, **probe)},
            "ads": {"port": self.ads_port}, "monitoring": {"enabled": False}, "cycle": {"realtime_priority": 0}})
        self.proc = ServiceProcess(self.config, folder)
        # no HTTP to wait on: the log's start-up line comes once the cycle runs
        started = wait_for(lambda: "service running" in self.log() or self.proc.proc.poll() is not None, 120)
        if not started or self.proc.proc.poll() is not None:
            self.proc.stop()
            raise AssertionError(f"the service did not start:\n{self.log()}")

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        self.proc.stop()

    def log(self) -> str:
        return self.proc.log_path.read_text()

    def variant(self, name: str, tls: dict | None = None, ads: dict | None = None):
        """The service's config with ``plc.tls`` and ``ads`` keys changed, as another file (for the probe)."""
        data = yaml.safe_load(self.config.read_text())
        data["plc"]["tls"].update(tls or {})
        data["ads"].update(ads or {})
        path = self.folder / f"{name}.yaml"
        path.write_text(yaml.safe_dump(data))
        return path


@pytest.fixture(scope="module")
def svc(tmp_path_factory):
    with TlsOnly(tmp_path_factory.mktemp("tls_only")) as s:
        yield s


def live(config, capsys, timeout_s: float = 30.0) -> tuple[int, str]:
    """``health --live`` until it exits 0 or ``timeout_s`` passes: its last exit code and output. On a busy
    machine the cycle may stall past the probe's 0.2 s window once; a probe that cannot reach the
    service never says live."""
    got = []

    def asked() -> bool:
        got[:] = [main(["health", "--live", "--config", str(config)]), capsys.readouterr().out]
        return got[0] == 0

    wait_for(asked, timeout_s, every=0.5)
    return got[0], got[1]


def nothing_listens(port: int) -> bool:
    with socket.socket() as s:
        return s.connect_ex(("127.0.0.1", port)) != 0


def test_the_start_line_names_modbus_tls_alone_and_no_plain_server(svc):
    line = next(x for x in svc.log().splitlines() if "service running" in x)
    assert f"PLC server Modbus/TCP Security 127.0.0.1:{svc.tls_port} alone" in line
    assert f":{svc.port}" not in line and nothing_listens(svc.port)


def test_live_over_modbus_tls_with_the_probe_certificate_the_config_names(svc, capsys):
    code, out = live(svc.config, capsys)
    assert code == 0, out
    assert out.startswith("live: the cycle count rose ")
    assert out.endswith(f"(Modbus/TCP Security 127.0.0.1:{svc.tls_port})\n") and out.count("\n") == 1


def test_without_a_probe_certificate_it_asks_over_ads(svc, capsys):
    cfg = svc.variant("no_probe_cert", tls={"probe_cert": None, "probe_key": None})
    code, out = live(cfg, capsys)
    assert code == 0, out
    assert out.startswith("live: ") and out.endswith(f"(ADS 127.0.0.1:{svc.ads_port})\n")


def test_with_neither_it_exits_2_naming_why_though_the_service_runs(svc, capsys):
    cfg = svc.variant("no_way", tls={"probe_cert": None, "probe_key": None}, ads={"enabled": False})
    assert main(["health", "--live", "--config", str(cfg)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and str(cfg) in err
    assert "Modbus/TCP Security alone" in err and "ads.enabled is false" in err and "probe_cert" in err


def test_a_probe_certificate_that_does_not_load_exits_2_naming_the_key(svc, capsys):
    cfg = svc.variant("bad_cert", tls={"probe_cert": str(svc.certs.viewer.key)})     # a key, not a certificate
    assert main(["health", "--live", "--config", str(cfg)]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.count("\n") == 1 and "plc.tls.probe_cert = " in err
