"""`stiffcomp modes DATA`: a tap test recorded in the HIL (its robot stub rings at 10 and 16 Hz, 3 %, along x
and y at the circle's centre) gives the modes back; ``-o`` writes a dynamics section the service config
takes; ``--plot`` draws the identified response over the measured one; ``--json`` carries what the text
advises; a bad record is a user error (exit 2, the file and the line)."""

from __future__ import annotations

import json

import pytest
from stiffcomp_testlib import ROOT

from hil.dynamics import tap_record, write_record
from hil.scenario import load_scenario
from service.config import load_config
from stiffness.model import StiffnessModel
from stiffness.yamlio import deep_update, dump_yaml, read_yaml
from tools.cli import main


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    sc = load_scenario()
    path = tmp_path_factory.mktemp("modes") / "tap.csv"
    write_record(tap_record(sc, StiffnessModel.from_yaml(sc.resolve(sc.truth))), path)
    return path


def test_the_tap_test_gives_the_stubs_modes_and_a_config_the_service_takes(record, tmp_path, capsys):
    out, png = tmp_path / "modes.yaml", tmp_path / "modes.png"
    assert main(["modes", str(record), "-o", str(out), "--plot", str(png), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    hz = [m["hz"] for m in got["modes"]]
    assert hz == pytest.approx([10.0, 16.0], rel=0.01)           # the stub's at the centre's reach (1.8 m)
    assert [m["damping"] for m in got["modes"]] == pytest.approx([0.03, 0.03], rel=0.1)
    assert abs(got["modes"][0]["direction"][0]) > 0.999 and abs(got["modes"][1]["direction"][1]) > 0.999
    assert got["lag_ms"] == pytest.approx(8.0, abs=0.5)        # the stub's residual low-pass, 40 Hz
    assert got["explained"] > 0.8 > got["explained_static"]
    assert got["written"] == str(out) and got["plot"] == str(png) and png.stat().st_size > 10_000
    config = read_yaml(ROOT / "config" / "default.yaml")
    deep_update(config, read_yaml(out))
    config["model"]["file"] = str(ROOT / "config" / "models" / "kr125_6dof.yaml")
    config["plc"]["register_map"] = str(ROOT / "config" / "registers.yaml")
    config["source"]["ati"]["dbc"] = str(ROOT / "config" / "ati_netft_can.dbc")
    config["source"]["replay"]["file"] = str(ROOT / "config" / "replay" / "demo_milling.blf")
    (tmp_path / "service.yaml").write_text(dump_yaml(config, sort_keys=False))
    cfg = load_config(tmp_path / "service.yaml")
    assert cfg.dynamics.enabled and len(cfg.dynamics.structure.modes) == 2
    assert got["config"]["dynamics"]["structure"] == read_yaml(out)["dynamics"]["structure"]


def test_a_bad_record_is_a_user_error_naming_the_line(record, tmp_path, capsys):
    lines = record.read_text().splitlines()
    lines[5] = lines[5].replace(",", ",x", 1)
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines) + "\n")
    assert main(["modes", str(bad)]) == 2
    err = capsys.readouterr().err
    assert f"{bad}: line 6: fx_N = 'x0.000' is not a number" in err and "1 problem" in err and "Traceback" not in err
    assert main(["modes", str(tmp_path / "missing.csv")]) == 2
    assert "missing.csv: file not found" in capsys.readouterr().err
