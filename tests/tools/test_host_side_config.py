"""`stiffcomp health` and `status` from the host with the site config copied out of the container
(issue 17, item 8): the file names a model, a replay and a register map inside the image; the commands
read only the addresses they need, so they answer about the service instead of exiting 2."""

from __future__ import annotations

import pytest
import yaml

from hil.testing import free_port, write_config
from service.app import Service
from service.config import load_config
from testlib.common import wait_for
from tools.cli import main

pytestmark = pytest.mark.realtime

IMAGE = "/opt/stiffcomp/config"         # where the image's config names its files


def site_config(folder, overrides: dict) -> str:
    """A config as the image carries it: every file named by a path that exists only inside the image."""
    path = write_config(folder, overrides)
    data = yaml.safe_load(path.read_text())
    data["model"]["file"] = f"{IMAGE}/models/kr125_6dof.yaml"
    data["plc"]["register_map"] = f"{IMAGE}/registers.yaml"
    data["source"]["replay"]["file"] = f"{IMAGE}/replay/demo_milling.blf"
    data["source"]["ati"]["dbc"] = f"{IMAGE}/ati_netft_can.dbc"
    site = folder / "site.yaml"
    site.write_text(yaml.safe_dump(data, sort_keys=False))
    return str(site)


def test_health_reads_only_the_monitoring_address(tmp_path, capsys):
    port = free_port()
    site = site_config(tmp_path, {"monitoring": {"port": port}})
    assert main(["health", "--config", site]) == 1                  # nothing runs: unhealthy, not a config error
    assert f"no answer from the service's I/O process at 127.0.0.1:{port}" in capsys.readouterr().out


def test_a_bad_monitoring_key_still_names_file_key_and_value(tmp_path, capsys):
    site = site_config(tmp_path, {"monitoring": {"port": 99999}})
    assert main(["health", "--config", site]) == 2
    assert "site.yaml: monitoring.port = 99999" in capsys.readouterr().err


def test_status_with_the_site_config_reads_the_running_service(tmp_path, capsys):
    port = free_port()
    runnable = write_config(tmp_path, {"plc": {"port": port}}, name="runnable.yaml")
    data = yaml.safe_load(runnable.read_text())
    site = site_config(tmp_path, {"plc": {"port": port}, "ads": {"port": data["ads"]["port"]},
                                  "monitoring": {"port": data["monitoring"]["port"]}})
    service = Service(load_config(runnable))
    try:
        service.start()
        assert wait_for(lambda: service.info.cycle_count > 0, timeout=60, every=0.001)  # a cycle's record, not the start's
        assert main(["status", "--config", site]) == 0
    finally:
        service.stop()
    out = capsys.readouterr()
    assert "RUN" in out.out and f"modbus 127.0.0.1:{port}" in out.out
    assert "is not on this machine" in out.err and "registers.yaml" in out.err
