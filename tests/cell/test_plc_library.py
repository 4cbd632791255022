"""`stiffcomp plc-library`: the PLC's side of the contract as TwinCAT 3 sources and PLCopen XML.

The sources are read back with blark and compared with the contract, the register map and the ADS
symbols the service serves; the committed plc/ files must equal what the shipped config generates.
"""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path
from xml.etree import ElementTree

import numpy as np
import pytest
import xmlschema
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from cell.plc.declarations import real_bounds, real_literal
from hil.testing import write_config
from plc_link.ads.symbols import IEC_TYPES, symbols_from_map
from plc_link.contract import Command, Fault, Status, TaskState
from plc_link.register_map import INT_RANGE, RegisterMap
from testlib.plc_source import constant, constants, enum_values, packed, struct_fields, summary
from tools.cli import main

ROOT = Path(__file__).resolve().parents[2]
SHIPPED = ROOT / "config" / "default.yaml"
COMMITTED = ROOT / "cell" / "plc" / "generated"
SCHEMA = ROOT / "tests" / "data" / "plcopen" / "tc6_xml_v201.xsd"    # PLCopen's, see the README beside it
SCHEMA_SHA256 = "db546a6d1847fee06268fa29baf9f643c8bdd75b3ad083eb9ebd4bfa93cb6c9b"
CONTRACT = "GVL_StiffCompContract"
RECORDS = {"to_plc": "ST_StiffCompToPlc", "from_plc": "ST_StiffCompFromPlc"}
TAGS = {"to_plc": "TO_PLC", "from_plc": "FROM_PLC"}
NS = "http://www.plcopen.org/xml/tc6_0201"


def generate(out: Path, config: Path = SHIPPED, *extra: str) -> int:
    return main(["plc-library", "-o", str(out), "--config", str(config), *extra])


def moved_map_config(tmp_path: Path) -> tuple[Path, RegisterMap]:
    """A config whose map moves the corrections up, leaves the deflection out and binds dq_q1 at a gap:
    other offsets, other gaps, a field that is not naturally aligned."""
    data = yaml.safe_load((ROOT / "config" / "registers.yaml").read_text())
    regs = data["to_plc"]["registers"]
    for r in regs:
        if r["name"].startswith("correction_q"):
            r["address"] += 0x33
    regs.append({"name": "dq_q1", "address": 0x8050})
    data["to_plc"]["registers"] = regs
    (tmp_path / "moved.yaml").write_text(yaml.safe_dump(data))
    cfg = write_config(tmp_path, {"plc": {"register_map": "moved.yaml", "port": 1502},
                                  "ads": {"net_id": "10.1.2.3.1.1"}})       # a whole config: plc-library reads it as run
    return cfg, RegisterMap.from_yaml(tmp_path / "moved.yaml")


def symbols(capsys, config: Path) -> list[dict]:
    capsys.readouterr()
    assert main(["symbols", "--json", "--config", str(config)]) == 0
    return json.loads(capsys.readouterr().out)


def test_the_committed_files_are_what_the_shipped_config_generates(tmp_path):
    assert generate(tmp_path) == 0
    made = sorted(p.relative_to(tmp_path) for p in tmp_path.rglob("*") if p.is_file())
    shipped = sorted(p.relative_to(COMMITTED) for p in COMMITTED.rglob("*") if p.is_file())
    assert made == shipped, "cell/plc/generated/ is not what `stiffcomp plc-library -o cell/plc/generated` writes now: regenerate it"
    for rel in made:
        assert (tmp_path / rel).read_bytes() == (COMMITTED / rel).read_bytes(), f"cell/plc/generated/{rel} is stale: regenerate it"
    assert {p.suffix for p in made} == {".TcDUT", ".TcGVL", ".TcPOU", ".xml"}


def test_every_twincat_file_parses_with_blark():
    code = summary(COMMITTED / "twincat")         # every file, each parsed without an error
    assert {"FB_StiffComp", "FB_StiffCompModbus"} <= set(code.function_blocks)
    assert "MAIN" in code.programs
    assert set(code.data_types) | set(code.globals) | set(code.function_blocks) | set(code.programs) == {
        p.stem for p in (COMMITTED / "twincat").iterdir()}


@pytest.fixture(scope="module")
def tc6() -> xmlschema.XMLSchema:
    return xmlschema.XMLSchema(SCHEMA)


def test_the_tc6_schema_is_the_copy_its_readme_names(tc6):
    assert hashlib.sha256(SCHEMA.read_bytes()).hexdigest() == SCHEMA_SHA256, f"{SCHEMA} is not the copy it was"
    assert SCHEMA_SHA256 in (SCHEMA.parent / "README.md").read_text()
    assert tc6.target_namespace == NS


def test_the_plcopen_file_validates_against_the_tc6_schema(tc6, tmp_path):
    tc6.validate(COMMITTED / "plcopen" / "StiffComp.xml")
    cfg, _ = moved_map_config(tmp_path)
    assert generate(tmp_path / "out", cfg, "--format", "plcopen") == 0
    tc6.validate(tmp_path / "out" / "plcopen" / "StiffComp.xml")
    assert not (tmp_path / "out" / "twincat").exists()


def _first(root: ElementTree.Element, path: str) -> ElementTree.Element:
    found = root.find(path, {"p": NS})
    assert found is not None, path
    return found


def _drop(root: ElementTree.Element, parent: str, child: str) -> None:
    node = _first(root, parent)
    node.remove(_first(node, child))


def _move_last(root: ElementTree.Element, parent: str, child: str) -> None:
    node = _first(root, parent)
    moved = _first(node, child)
    node.remove(moved)
    node.append(moved)


def _retag(root: ElementTree.Element, path: str, tag: str) -> None:
    _first(root, path).tag = f"{{{NS}}}{tag}"


BREAKS = {       # each leaves the file well-formed XML that the schema must refuse
    "no fileHeader": lambda root: _drop(root, ".", "p:fileHeader"),
    "no coordinateInfo": lambda root: _drop(root, "p:contentHeader", "p:coordinateInfo"),
    "a data type without its base type": lambda root: _drop(root, ".//p:dataType", "p:baseType"),
    "a struct field without its type": lambda root: _drop(root, ".//p:struct/p:variable", "p:type"),
    "a block's interface after its body": lambda root: _move_last(root, ".//p:pou", "p:interface"),
    "an unknown pouType": lambda root: _first(root, ".//p:pou").set("pouType", "FUNCTION_BLOCK"),
    "an unknown elementary type": lambda root: _retag(root, ".//p:struct/p:variable/p:type/p:UINT", "UINT16"),
}


@pytest.mark.parametrize("broken", BREAKS)
def test_a_broken_plcopen_file_fails_the_schema(tc6, broken):
    root = ElementTree.parse(COMMITTED / "plcopen" / "StiffComp.xml").getroot()
    tc6.validate(root)                                  # whole, it passes as a tree as well as a file
    BREAKS[broken](root)
    with pytest.raises(xmlschema.XMLSchemaValidationError):
        tc6.validate(root)


def test_the_plcopen_bodies_are_the_twincat_files_text():
    """The schema takes a body as free text, so the bodies blark parsed must be the very same."""
    root = ElementTree.parse(COMMITTED / "plcopen" / "StiffComp.xml").getroot()
    pous = root.findall(".//p:pou", {"p": NS})
    assert {p.get("name") for p in pous} == {f.stem for f in (COMMITTED / "twincat").glob("*.TcPOU")}
    for pou in pous:
        tc = ElementTree.parse(COMMITTED / "twincat" / f"{pou.get('name')}.TcPOU").getroot()
        assert "".join(_first(pou, "p:body/p:ST").itertext()) == tc.find("POU/Implementation/ST").text


def test_a_struct_that_needs_packing_says_so_in_the_plcopen_file_too(tmp_path):
    cfg, _ = moved_map_config(tmp_path)
    assert generate(tmp_path / "out", cfg) == 0
    for folder, packed_to_plc in ((tmp_path / "out", True), (COMMITTED, False)):
        root = ElementTree.parse(folder / "plcopen" / "StiffComp.xml").getroot()
        types = {t.get("name"): t for t in root.iter(f"{{{NS}}}dataType")}
        attrs = {r: {(a.get("Name"), a.get("Value")) for a in types[r].iter(f"{{{NS}}}Attribute")}
                 for r in RECORDS.values()}
        for record, found in attrs.items():
            assert (("pack_mode", "1") in found) == packed(folder / "twincat" / f"{record}.TcDUT"), record
        assert (("pack_mode", "1") in attrs["ST_StiffCompToPlc"]) == packed_to_plc


def check_against_map(folder: Path, rmap: RegisterMap, served: list[dict]) -> None:
    """Every register and ADS symbol, read back from the parsed sources in ``folder``."""
    code = summary(folder, "*.Tc[DG]*")          # the types and global lists
    group = constant(code, CONTRACT, "ADS_IGRP")
    by_symbol = {s["name"]: s for s in served}
    for direction, record in RECORDS.items():
        fields = {f.name: f for f in struct_fields(code, record)}
        regs = [r for r in rmap.registers if r.direction == direction]
        start = constant(code, CONTRACT, f"ADS_IOFFS_{TAGS[direction]}")
        mb_addr = constant(code, CONTRACT, f"MB_ADDR_{TAGS[direction]}")
        size = sum(f.size for f in fields.values())
        assert constant(code, CONTRACT, f"CB_{TAGS[direction]}") == size
        assert 2 * constant(code, CONTRACT, f"MB_WORDS_{TAGS[direction]}") == size
        assert {n for n in fields if not n.startswith("reserved_")} == {r.name for r in regs}
        for r in regs:
            f = fields[r.name]
            sym = by_symbol.pop(f"GVL_Comp.{r.name}")
            assert (f.type, f.size) == (IEC_TYPES[r.type], 2 * r.count) == (sym["type"], sym["size"])
            assert mb_addr + f.offset // 2 == r.address, r.name
            assert (group, start + f.offset) == (sym["index_group"], sym["index_offset"]), r.name
        if not packed(folder / f"{record}.TcDUT"):    # then natural alignment must give the same layout
            assert all(f.offset % min(f.size, 4) == 0 for f in fields.values() if not f.type.startswith("ARRAY"))
            assert size % max(min(f.size, 4) for f in fields.values()) == 0
    info = {f.name: f for f in struct_fields(code, "ST_StiffCompTaskInfo")}
    assert constant(code, CONTRACT, "ADS_CB_TASKINFO") == sum(f.size for f in info.values())
    for name, sym in by_symbol.items():
        f = info[name.removeprefix("TwinCAT_SystemInfoVarList._TaskInfo[1].")]
        assert (f.type, f.offset, f.size) == (sym["type"], sym["index_offset"], sym["size"]), name
        assert constant(code, CONTRACT, "ADS_IGRP_TASKINFO") == sym["index_group"]


def test_every_symbol_and_register_has_its_offset_and_type_in_the_sources(capsys):
    check_against_map(COMMITTED / "twincat", RegisterMap.from_yaml(ROOT / "config" / "registers.yaml"),
                      symbols(capsys, SHIPPED))


def test_another_map_gives_its_own_offsets_gaps_and_packing(tmp_path):
    cfg, rmap = moved_map_config(tmp_path)
    assert generate(tmp_path / "out", cfg, "--format", "twincat") == 0
    folder = tmp_path / "out" / "twincat"
    check_against_map(folder, rmap, [s.as_dict() for s in symbols_from_map(rmap)])   # what `symbols` prints
    assert packed(folder / "ST_StiffCompToPlc.TcDUT")          # dq_q1 (a REAL) at an odd word
    assert not packed(COMMITTED / "twincat" / "ST_StiffCompToPlc.TcDUT")
    code = summary(folder, "*.TcGVL")
    assert str(code.globals["GVL_StiffCompSettings"].declarations["sAmsNetId"].value) == "'10.1.2.3.1.1'"
    assert constant(code, "GVL_StiffCompSettings", "nModbusPort") == 1502
    assert not (tmp_path / "out" / "plcopen").exists()


def test_every_contract_bit_and_state_has_the_contracts_value():
    code = summary(COMMITTED / "twincat", "*.Tc[DG]*")
    for prefix, flags in (("CMD_", Command), ("STATUS_", Status), ("FAULT_", Fault)):
        assert constants(code, CONTRACT, prefix) == {f.name: int(f) for f in flags}
    assert enum_values(code, "E_StiffCompTaskState") == {s.name: int(s) for s in TaskState}
    body = (COMMITTED / "twincat" / "FB_StiffComp.TcPOU").read_text()
    decoded = dict(re.findall(r"(st\w+\.b\w+) := \(n\w+Word AND GVL_StiffCompContract\.(\w+)\) <> 0;", body))
    status = {f.name for f in struct_fields(code, "ST_StiffCompStatus")}
    faults = {f.name for f in struct_fields(code, "ST_StiffCompFaults")}
    assert sorted(decoded.values()) == sorted([f"STATUS_{s.name}" for s in Status] + [f"FAULT_{f.name}" for f in Fault])
    assert {k.split(".")[1] for k in decoded if k.startswith("stStatus")} == status
    assert {k.split(".")[1] for k in decoded if k.startswith("stFaults")} == faults


def test_the_blocks_are_the_same_but_for_their_requests():
    ads = (COMMITTED / "twincat" / "FB_StiffComp.TcPOU").read_text()
    modbus = (COMMITTED / "twincat" / "FB_StiffCompModbus.TcPOU").read_text()
    assert "ADSREAD" in ads and "ADSWRITE" in ads
    assert "FB_MBReadInputRegs" in modbus and "FB_MBWriteRegs" in modbus      # to_plc: input registers
    step5 = ads.index("// 5.")
    assert ads[step5:] == modbus[modbus.index("// 5."):]


def refused(capsys, code: int, *words: str) -> None:
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    for w in words:
        assert w in err


def test_a_missing_parent_folder_or_a_file_is_refused_and_nothing_written(tmp_path, capsys):
    refused(capsys, generate(tmp_path / "no" / "out"), "-o", "does not exist")
    assert not (tmp_path / "no").exists()
    (tmp_path / "f").write_text("x")
    refused(capsys, generate(tmp_path / "f"), "-o", "is a file")
    assert (tmp_path / "f").read_text() == "x"


def test_a_map_with_a_gap_between_the_plcs_registers_is_refused(tmp_path, capsys):
    data = yaml.safe_load((ROOT / "config" / "registers.yaml").read_text())
    data["from_plc"]["registers"][-1]["address"] += 1           # payload_index one word further
    (tmp_path / "gap.yaml").write_text(yaml.safe_dump(data))
    write_config(tmp_path, {"plc": {"register_map": "gap.yaml"}})
    refused(capsys, generate(tmp_path / "out", tmp_path / "service.yaml"), "payload_index", "gap")
    assert not (tmp_path / "out").exists()


def test_the_plcopen_configuration_has_a_resource_whose_task_runs_main():
    root = ElementTree.parse(COMMITTED / "plcopen" / "StiffComp.xml").getroot()
    config = _first(root, ".//p:configuration")
    task = _first(config, "p:resource/p:task")
    assert (task.get("interval"), task.get("priority")) == ("T#1MS", "20")
    assert _first(task, "p:pouInstance").get("typeName") == "MAIN"
    assert {g.get("name") for g in config.findall("p:globalVars", {"p": NS})} == {CONTRACT, "GVL_StiffCompSettings"}


def test_bit_words_and_their_bits_are_word():
    """IEC's AND and OR take bit strings: the bits, the words the blocks decode and the command they build."""
    code = summary(COMMITTED / "twincat")
    gvl = code.globals[CONTRACT].declarations
    assert {str(d.type) for n, d in gvl.items() if str(n).startswith(("CMD_", "STATUS_", "FAULT_"))} == {"WORD"}
    for block in ("FB_StiffComp", "FB_StiffCompModbus"):
        decl = code.function_blocks[block].declarations
        assert {n: str(decl[n].type) for n in ("nStatusWord", "nFaultWord", "nCommand")} == dict.fromkeys(
            ("nStatusWord", "nFaultWord", "nCommand"), "WORD")


@pytest.mark.parametrize(("host", "words"), [
    ("0.0.0.0", ("plc.host", "'0.0.0.0'", "bind address", "--modbus-host")),
    ("stiffcomp.cell.example", ("plc.host", "host name", "IPv4", "--modbus-host")),
    ("a-very-long-host-name-for-the-service.example", ("host name", "STRING(15)")),
    ("::", ("IPv6",)),
])
def test_a_host_the_plc_cannot_dial_is_refused_and_nothing_written(tmp_path, capsys, host, words):
    write_config(tmp_path, {"plc": {"host": host}})          # a whole config: plc-library reads it as run does
    refused(capsys, generate(tmp_path / "out", tmp_path / "service.yaml"), str(tmp_path / "service.yaml"), *words)
    assert not (tmp_path / "out").exists()


def test_the_plcs_target_is_taken_from_modbus_host_where_plc_host_binds_all(tmp_path, capsys):
    write_config(tmp_path, {"plc": {"host": "0.0.0.0"}})
    assert generate(tmp_path / "out", tmp_path / "service.yaml", "--modbus-host", "192.168.10.20") == 0
    code = summary(tmp_path / "out" / "twincat", "*.TcGVL")
    assert str(code.globals["GVL_StiffCompSettings"].declarations["sModbusHost"].value) == "'192.168.10.20'"
    capsys.readouterr()
    refused(capsys, generate(tmp_path / "again", tmp_path / "service.yaml", "--modbus-host", "0.0.0.0"),
            "--modbus-host", "bind address")


@pytest.mark.parametrize(("host", "noted"), [("127.0.0.1", True), ("192.168.10.20", False)])
def test_a_loopback_target_is_written_with_a_note_that_only_this_machine_reaches_it(tmp_path, capsys, host, noted):
    """127.0.0.1 is right for a PLC on the service's own IPC and wrong for any other: written, and said."""
    write_config(tmp_path, {"plc": {"host": host}})
    assert generate(tmp_path / "out", tmp_path / "service.yaml") == 0
    err = capsys.readouterr().err
    assert ("only a PLC on this machine reaches" in err and "--modbus-host" in err) == noted, err


def test_a_scaled_count_or_bit_word_is_refused(tmp_path, capsys):
    data = yaml.safe_load((ROOT / "config" / "registers.yaml").read_text())
    data["to_plc"]["registers"][0]["scale"] = 10                 # the heartbeat
    (tmp_path / "m.yaml").write_text(yaml.safe_dump(data))
    write_config(tmp_path, {"plc": {"register_map": "m.yaml"}})
    refused(capsys, generate(tmp_path / "out", tmp_path / "service.yaml"), "heartbeat", "scale = 10", "scale 1")


@given(st.floats(1e-9, 1e9))
@settings(max_examples=50)
def test_a_scale_is_written_as_an_iec_real_literal(x):
    text = real_literal(x)
    assert re.fullmatch(r"\d+\.\d+(E-?\d+)?", text), text
    assert float(text) == x


@pytest.mark.parametrize("code", sorted(INT_RANGE))
def test_the_limits_before_a_real_to_int_conversion_lie_inside_the_type(code):
    """REAL_TO_DINT of a REAL outside DINT overflows: the limits are the widest REALs inside the range."""
    lo, hi = real_bounds(code)
    lowest, highest = INT_RANGE[code]
    assert float(np.float32(lo)) == lo and float(np.float32(hi)) == hi
    assert lowest <= lo < hi <= highest
    assert float(np.nextafter(np.float32(hi), np.float32(np.inf))) > highest
    assert float(np.nextafter(np.float32(lo), np.float32(-np.inf))) < lowest
