"""A server that cannot listen says why and what to do, naming the config's key: a privileged port
(`stiffcomp run` as a process without CAP_NET_BIND_SERVICE, on 802), a port another process holds, an
address this machine does not have. pymodbus itself says only "Could not start listen, please check
address"."""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from hil.testing import CONFIG, ROOT, free_port, write_config
from io_base.errors import PlcError
from io_base.listen import PRIVILEGED_BELOW
from io_process.server import IoSettings, IoThread
from io_process.settings import MonitoringSettings
from plc_link.ads.settings import AdsSettings
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from plc_link.settings import PlcSettings
from testlib.tls_certs import cert_set, tls_settings

pytestmark = pytest.mark.realtime

LOW_PORT = 802


def unprivileged_prefix() -> list[str] | None:
    """How to start a process here that may not bind ports below 1024: as root, setpriv dropping
    CAP_NET_BIND_SERVICE; as another user, nothing. None where such a process may bind them all the same
    (net.ipv4.ip_unprivileged_port_start at or below 802, as in a container) or setpriv is missing."""
    start = Path("/proc/sys/net/ipv4/ip_unprivileged_port_start")
    if start.exists() and int(start.read_text()) <= LOW_PORT:
        return None
    if os.geteuid() != 0:
        return []
    setpriv = shutil.which("setpriv")
    return None if setpriv is None else [setpriv, "--bounding-set", "-net_bind_service",
                                         "--inh-caps", "-net_bind_service"]


def test_the_service_on_a_privileged_port_says_so_and_what_to_do(tmp_path):
    prefix = unprivileged_prefix()
    if prefix is None:
        pytest.skip("every process here may bind port 802 (ip_unprivileged_port_start), or setpriv is missing")
    cs = cert_set(tmp_path / "certs")
    cfg = write_config(tmp_path, {"plc": {"port": free_port(), "tls": tls_settings(cs, LOW_PORT, plain=False)},
                                  "cycle": {"realtime_priority": 0}})
    p = subprocess.run([*prefix, sys.executable, "-m", "tools.cli", "run", "--config", str(cfg), "--duration", "1"],
                       cwd=ROOT, capture_output=True, text=True, timeout=180, check=False)
    assert p.returncode == 2, p.stderr
    last = p.stderr.splitlines()[-1]
    assert last.startswith(f"stiffcomp run: error: cannot serve Modbus/TCP Security on 127.0.0.1:{LOW_PORT}: ")
    assert f"port {LOW_PORT} is a privileged port (below {PRIVILEGED_BELOW})" in last
    assert "CAP_NET_BIND_SERVICE" in last and f"set plc.tls.port to a port of {PRIVILEGED_BELOW} or above" in last
    assert "Could not start listen" not in p.stderr and "Traceback" not in p.stderr


@pytest.fixture
def image():
    img = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    yield img
    img.close()


def refusal(image, settings: IoSettings) -> str:
    with pytest.raises(PlcError) as e:
        IoThread(image, settings).start()
    return str(e.value)


def test_a_port_another_process_holds_is_named_with_its_key(image):
    with socket.create_server(("127.0.0.1", 0)) as held:
        port = held.getsockname()[1]
        cases = {"plc.port": IoSettings(plc=PlcSettings(port=port)),
                 "ads.port": IoSettings(plc=PlcSettings(role="none"), ads=AdsSettings(port=port)),
                 "monitoring.port": IoSettings(plc=PlcSettings(role="none"), ads=AdsSettings(enabled=False),
                                               monitoring=MonitoringSettings(port=port))}
        for key, settings in cases.items():
            msg = refusal(image, settings)
            assert f"127.0.0.1:{port}: port {port} is in use by another process" in msg, msg
            assert f"set {key} to a free port" in msg and "Could not start listen" not in msg


def test_an_address_this_machine_does_not_have_is_named(image):
    msg = refusal(image, IoSettings(plc=PlcSettings(host="192.0.2.1", port=free_port())))   # TEST-NET-1
    assert "192.0.2.1 is not an address of this machine" in msg and "plc.port" in msg, msg
