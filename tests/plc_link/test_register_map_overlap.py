"""Blocks of one table must not overlap: the PLC's writes would land in the service's block."""

import pytest
import yaml

from hil.testing import CONFIG
from plc_link.errors import RegisterMapError
from plc_link.register_map import RegisterMap


def test_overlapping_blocks_in_one_table_are_refused(tmp_path):
    data = yaml.safe_load((CONFIG / "registers.yaml").read_text())
    data["to_plc"]["table"] = "holding_registers"
    data["to_plc"]["start"] = data["from_plc"]["start"]
    shift = data["to_plc"]["start"] - min(r["address"] for r in data["to_plc"]["registers"])
    for r in data["to_plc"]["registers"]:
        r["address"] += shift
    path = tmp_path / "overlap.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(RegisterMapError, match="overlap in holding_registers"):
        RegisterMap.from_yaml(path)
    RegisterMap.from_yaml(CONFIG / "registers.yaml")          # the shipped map is fine
