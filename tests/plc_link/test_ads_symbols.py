"""`stiffcomp symbols`: the ADS symbols come from the register map, at the %MB offsets docs/ads.md gives."""

from __future__ import annotations

import json
from itertools import pairwise

from hil.testing import CONFIG
from plc_link.register_map import RegisterMap
from tools.cli import main

SIZE = {"uint16": 2, "int16": 2, "uint32": 4, "int32": 4, "float32": 4}


def test_symbols_json_is_the_register_map_at_its_mb_offsets(capsys):
    assert main(["symbols", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert {tuple(sorted(r)) for r in rows} == {("index_group", "index_offset", "name", "size", "type", "writable")}
    rmap = RegisterMap.from_yaml(CONFIG / "registers.yaml")
    to, fr = rmap.blocks["to_plc"], rmap.blocks["from_plc"]
    by = {r["name"]: r for r in rows}
    for reg in rmap.registers:
        s = by.pop(f"GVL_Comp.{reg.name}")
        # word index in [to_plc block, then from_plc block], two bytes per word
        word = reg.address - to.start if reg.direction == "to_plc" else to.size + reg.address - fr.start
        assert (s["index_group"], s["index_offset"], s["size"]) == (0x4020, 2 * word, SIZE[reg.type])
        assert s["writable"] is (reg.direction == "from_plc")
    assert set(by) == {f"TwinCAT_SystemInfoVarList._TaskInfo[1].{n}" for n in
                       ("CycleTime", "CycleCount", "LastExecTime", "CycleTimeExceeded", "ExceedCounter")}
    assert all(s["index_group"] == 0x4040 and not s["writable"] for s in by.values())
    spans = sorted((r["index_group"], r["index_offset"], r["index_offset"] + r["size"]) for r in rows)
    assert all(a[0] != b[0] or a[2] <= b[1] for a, b in pairwise(spans))     # no two overlap


def test_symbols_table_prints(capsys):
    assert main(["symbols"]) == 0
    out = capsys.readouterr().out
    assert "GVL_Comp.correction_q6" in out and "CycleTimeExceeded" in out
