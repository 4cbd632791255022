"""One way from a service config to its register map (`ServiceConfig.register_map`): a broken map is
refused with the config file and the key ``plc.register_map`` named, by every command that reads it."""

from __future__ import annotations

import re

import pytest
import yaml

from hil.testing import CONFIG, write_config
from service.app import Service
from service.config import load_config
from service.errors import ServiceConfigError
from testlib.common import ROOT
from tools.cli import main


@pytest.fixture
def broken(tmp_path):
    """A config whose register map binds a name twice."""
    data = yaml.safe_load((CONFIG / "registers.yaml").read_text())
    regs = data["to_plc"]["registers"]
    regs.append({**regs[-1], "address": regs[-1]["address"] + 0x100})
    (tmp_path / "broken.yaml").write_text(yaml.safe_dump(data))
    return write_config(tmp_path, {"plc": {"register_map": "broken.yaml"}})


def test_the_config_names_its_file_and_key_for_a_broken_map(broken):
    cfg = load_config(broken)
    with pytest.raises(ServiceConfigError) as e:
        cfg.register_map()
    assert str(e.value).startswith(f"{broken}: plc.register_map = 'broken.yaml': ")
    assert "broken.yaml" in str(e.value).split(": plc.register_map = ", 1)[1]
    with pytest.raises(ServiceConfigError, match=re.escape(f"{broken}: plc.register_map = 'broken.yaml'")):
        Service(cfg)


@pytest.mark.parametrize("command", ["registers", "symbols"])
def test_every_command_names_the_key(broken, command, capsys):
    assert main([command, "--config", str(broken)]) == 2
    err = capsys.readouterr().err
    assert f"{broken}: plc.register_map = 'broken.yaml'" in err


def test_the_good_map_loads_through_the_config(tmp_path):
    rmap = load_config(write_config(tmp_path)).register_map()
    assert "correction_q1" in rmap.codecs["to_plc"].names


def test_no_other_place_reads_the_configs_map_itself():
    """The service, the tools and the HIL read the map the config names through cfg.register_map(), the
    health probe through its light endpoints; both end in `io_process.endpoints.load_register_map`."""
    hits = [f"{p.relative_to(ROOT)}:{n}" for folder in ("service", "tools", "hil", "io_process", "plc_link", "robot_road", "io_base")
            for p in sorted((ROOT / folder).rglob("*.py"))
            for n, line in enumerate(p.read_text().splitlines(), 1)
            if "RegisterMap.from_yaml(" in line and p != ROOT / "io_process" / "endpoints.py"]
    assert hits == []
