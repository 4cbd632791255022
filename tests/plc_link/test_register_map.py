"""The register map: validation, the JSON listing, codecs (round trip, low word first)."""

from __future__ import annotations

import json
import struct
from itertools import pairwise

import numpy as np
import pytest
import yaml

from hil.testing import CONFIG
from plc_link.errors import RegisterMapError
from plc_link.register_map import REQUIRED, BlockCodec, Register, RegisterMap
from tools.cli import main

MAP = CONFIG / "registers.yaml"


def test_default_map_holds_every_required_name():
    m = RegisterMap.from_yaml(MAP)
    names = {r.name for r in m.registers}
    assert set(REQUIRED["to_plc"]) | set(REQUIRED["from_plc"]) <= names
    assert all(r.table == "holding_registers" for r in m.registers if r.direction == "from_plc")


def test_registers_json_lists_the_documented_fields(capsys):
    assert main(["registers", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert {tuple(sorted(r)) for r in rows} == {tuple(sorted(["name", "table", "address", "type", "count", "unit",
                                                              "scale", "direction"]))}
    by = {r["name"]: r for r in rows}
    assert by["correction_q1"] == {"name": "correction_q1", "table": "input_registers", "address": 0x8010,
                                   "type": "float32", "count": 2, "unit": "deg", "scale": 1.0,
                                   "direction": "to_plc"}
    assert by["command_word"]["direction"] == "from_plc" and by["command_word"]["table"] == "holding_registers"


def test_registers_table_prints(capsys):
    assert main(["registers"]) == 0
    out = capsys.readouterr().out
    assert "low word first" in out and "correction_q6" in out


def test_codec_round_trip_all_types():
    regs = [Register("a", "input_registers", 10, "uint16", 1, "", 1.0, "to_plc"),
            Register("b", "input_registers", 11, "int16", 1, "", 10.0, "to_plc"),
            Register("c", "input_registers", 12, "uint32", 2, "", 1.0, "to_plc"),
            Register("d", "input_registers", 16, "int32", 2, "", 1.0, "to_plc"),
            Register("e", "input_registers", 18, "float32", 2, "", 1.0, "to_plc")]
    codec = BlockCodec(regs, 10, 20)
    values = [65535, -12.3, 4_000_000_000, -2_000_000_000, 3.25]
    words = codec.encode(values)
    assert len(words) == 10 and words[4:6] == [0, 0]          # the gap at 14..15 stays zero
    assert all(0 <= w <= 0xFFFF for w in words)
    np.testing.assert_allclose(codec.decode(words), values, rtol=1e-6)


def test_32_bit_values_are_low_word_first():
    m = RegisterMap.from_yaml(MAP)
    codec = m.codecs["to_plc"]
    vals = [0.0] * len(codec.names)
    vals[codec.index["cycle_count"]] = 0x12345678
    vals[codec.index["correction_q1"]] = 1.0
    words = codec.encode(vals)
    k = m.by_name["cycle_count"].address - codec.start
    assert words[k:k + 2] == [0x5678, 0x1234]
    k = m.by_name["correction_q1"].address - codec.start
    assert words[k:k + 2] == list(struct.unpack("<HH", struct.pack("<f", 1.0))) == [0x0000, 0x3F80]


def test_integers_are_clamped_not_wrapped():
    codec = BlockCodec([Register("a", "input_registers", 0, "uint16", 1, "", 1.0, "to_plc"),
                        Register("b", "input_registers", 1, "int16", 1, "", 1.0, "to_plc")], 0, 2)
    assert codec.encode([70000, -40000]) == [65535, 0x8000]
    assert codec.encode([float("nan"), 5]) == [0, 5]


@pytest.mark.parametrize("edit, match", [
    (lambda d: d["to_plc"]["registers"].append({"name": "dq_q1", "address": 0x8000, "type": "uint16"}), "overlaps"),
    (lambda d: d["to_plc"]["registers"].pop(0), "register 'heartbeat' is missing"),
    (lambda d: d["from_plc"].update(table="input_registers"), "can write only holding_registers"),
    (lambda d: d["to_plc"]["registers"][0].update(address=0x9000), "must lie in"),
    (lambda d: d["to_plc"]["registers"][0].update(type="uint64"), "type"),
    (lambda d: d["to_plc"]["registers"][0].update(colour="red"), "colour is not a known key"),
])
def test_bad_maps_are_refused_with_the_key(tmp_path, edit, match):
    data = yaml.safe_load(MAP.read_text())
    edit(data)
    path = tmp_path / "map.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(RegisterMapError, match=match) as e:
        RegisterMap.from_yaml(path)
    assert str(path) in str(e.value)


def test_service_accepts_a_map_without_optional_registers_and_refuses_unknown_ones(tmp_path):
    from hil.testing import write_config
    from service.app import Service
    from service.config import load_config
    from service.errors import ServiceConfigError

    data = yaml.safe_load(MAP.read_text())
    data["to_plc"]["registers"] = [r for r in data["to_plc"]["registers"]
                                   if r["name"] not in ("task_state", "cycle_time_us", "period_jitter_us")]
    (tmp_path / "small.yaml").write_text(yaml.safe_dump(data))
    s = Service(load_config(write_config(tmp_path, {"plc": {"register_map": str(tmp_path / "small.yaml")}})))
    try:
        s.work(0.0, False)
        assert s.image.outputs()["cycle_count"] == 1
    finally:
        s.stop()
    data["to_plc"]["registers"].append({"name": "spindle_speed", "address": 0x8050, "type": "float32"})
    (tmp_path / "extra.yaml").write_text(yaml.safe_dump(data))
    with pytest.raises(ServiceConfigError, match="'spindle_speed' is not a value the service produces"):
        Service(load_config(write_config(tmp_path, {"plc": {"register_map": str(tmp_path / "extra.yaml")}})))


@pytest.mark.parametrize("names", [("acc_x", "acc_y", "acc_z", "acc_samples"), ("plan_time_s", "plan_engagement"),
                                   ("payload_index",)])
def test_values_added_follow_the_last_from_plc_register_and_load_again(tmp_path, names):
    m = RegisterMap.from_yaml(MAP)
    if "payload_index" in names:                       # the shipped map binds it: add it to a map without it
        data = yaml.safe_load(MAP.read_text())
        data["from_plc"]["registers"] = [r for r in data["from_plc"]["registers"] if r["name"] != "payload_index"]
        (tmp_path / "without.yaml").write_text(yaml.safe_dump(data))
        m = RegisterMap.from_yaml(tmp_path / "without.yaml")
    end = max(r.address + r.count for r in m.registers if r.direction == "from_plc")
    (tmp_path / "more.yaml").write_text(yaml.safe_dump(m.extended(names)))
    more = RegisterMap.from_yaml(tmp_path / "more.yaml")
    added = sorted((r for r in more.registers if r.name in names), key=lambda r: r.address)
    assert [r.name for r in added] == list(names) and added[0].address == end
    assert all(a.address + a.count == b.address for a, b in pairwise(added))      # no gap
    assert [r.as_dict() for r in more.registers if r.name not in names] == [r.as_dict() for r in m.registers]


def test_a_value_bound_already_or_not_the_plcs_is_not_added():
    m = RegisterMap.from_yaml(MAP)
    with pytest.raises(RegisterMapError, match="'q1'.*binds it already"):
        m.extended(["q1"])
    with pytest.raises(RegisterMapError, match="'dx'.*not a value the PLC writes"):
        m.extended(["dx"])
