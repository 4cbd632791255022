"""`stiffcomp modes DATA`: a tap test recorded in the HIL (its robot stub rings at 10 and 16 Hz, 3 %, along x
and y at the circle's centre) gives the modes back; ``-o`` writes a dynamics section the service config
takes; ``--plot`` draws the identified response over the measured one; ``--json`` carries what the text
advises; a bad record is a user error (exit 2, the file and the line).

What a record does not excite is not identified: tapped along x only, it says so and refuses a second mode
(one mode it gives back); a tap too weak for the noise, a file cut off in its last line, t_s in milliseconds
and a bad option are each refused in one line, exit 2, nothing written (an option before the record is read)."""

from __future__ import annotations

import json

import pytest

from hil.dynamics import tap_record, write_record
from hil.scenario import load_scenario
from service.config import load_config
from stiffness.files.yaml_schema import deep_update, dump_yaml, read_yaml
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import ROOT
from tools.cli import main

pytestmark = pytest.mark.slow


def tapped(folder, name, **kw):
    sc = load_scenario()
    path = folder / name
    write_record(tap_record(sc, StiffnessModel.from_yaml(sc.resolve(sc.truth)), **kw), path)
    return path


@pytest.fixture(scope="module")
def record(tmp_path_factory):
    return tapped(tmp_path_factory.mktemp("modes"), "tap.csv")


def refused(argv, capsys) -> str:
    """The one line `stiffcomp modes ARGV` refuses with (exit 2, no traceback)."""
    assert main(["modes", *argv]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    return err


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
    exc = got["excitation"]                                      # tapped along x, y and z: all three excited
    assert exc["excited"] == ["x", "y", "z"] and min(exc["explains"].values()) > exc["threshold"] > 10
    assert min(exc["modes"]) > 100 * exc["threshold"]


def test_a_record_tapped_along_x_only_says_so_and_gives_one_mode(tmp_path, capsys):
    """The stub tapped along x alone: its 16 Hz mode along y does not move; two modes are refused (the
    second is noise the fit made up), nothing is written; one mode comes back as the 10 Hz along x."""
    rec, out = tapped(tmp_path, "x.csv", axes=(0,)), tmp_path / "modes.yaml"
    err = refused([str(rec), "-o", str(out)], capsys)
    assert f"{rec}: mode 2 of 2" in err and "is not in the record" in err, err
    assert "excites x (" in err and "not y, z (no force along them)" in err and "ask for 1 mode(s)" in err, err
    assert not out.exists()
    assert main(["modes", str(rec), "--modes", "1", "--json", "-o", str(out)]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["modes"][0]["hz"] == pytest.approx(10.0, rel=0.01) and abs(got["modes"][0]["direction"][0]) > 0.999
    exc = got["excitation"]
    assert exc["excited"] == ["x"] and exc["explains"]["y"] is None and exc["explains"]["z"] is None
    assert exc["modes"][0] > 100 * exc["threshold"] and out.exists()


def test_a_tap_too_weak_for_the_noise_is_refused(tmp_path, capsys):
    """1 N taps move the stub by a fraction of the tracker's 1 um noise: no direction is excited."""
    rec, out = tapped(tmp_path, "weak.csv", peak_n=1.0), tmp_path / "modes.yaml"
    err = refused([str(rec), "--modes", "1", "-o", str(out)], capsys)
    assert f"{rec}: the force excites no direction; not x (" in err and "nothing can be identified" in err, err
    assert not out.exists()


def test_a_record_cut_off_in_its_last_line_is_refused_naming_it(record, tmp_path, capsys):
    """Cut inside the last number of a row: the row still has its seven numbers, but no line break."""
    text = record.read_text()
    cut = text[:text.index("\n", len(text) // 3) + 1]
    last = cut.count("\n") + 1
    row = text[len(cut):text.index("\n", len(cut))]
    bad = tmp_path / "cut.csv"
    bad.write_text(cut + row[:-3])
    assert len(row[:-3].split(",")) == 7
    err = refused([str(bad), "-o", str(tmp_path / "modes.yaml")], capsys)
    assert f"{bad}: line {last}: ends without a line break: the file was cut off" in err, err
    assert not (tmp_path / "modes.yaml").exists()


def test_t_s_in_milliseconds_is_refused_naming_the_column(record, tmp_path, capsys):
    lines = record.read_text().splitlines()
    rows = [f"{1000.0 * float(x.split(',', 1)[0]):.1f},{x.split(',', 1)[1]}" for x in lines[1:]]
    bad = tmp_path / "ms.csv"
    bad.write_text("\n".join([lines[0], *rows]) + "\n")
    err = refused([str(bad)], capsys)
    assert f"{bad}: column t_s: the rows are 1 s apart" in err and "is t_s in milliseconds?" in err, err


@pytest.mark.parametrize("option, message", [
    (["--max-lag-ms", "-5"], "--max-lag-ms -5: must be a finite number above 0 and at most 100 \\(ms: the arm's lag"),
    (["--max-lag-ms", "0"], "--max-lag-ms 0: must be a finite number above 0 and at most 100"),
    (["--max-lag-ms", "1e6"], "--max-lag-ms 1e\\+06: must be a finite number above 0 and at most 100"),
    (["--max-lag-ms", "nan"], "--max-lag-ms nan: must be a finite number"),
    (["--plot", "{tmp}/m.txt"], "--plot {tmp}/m.txt: the suffix says the image's format; it must be one of .*\\.png"),
    (["--plot", "{tmp}/missing/m.png"], "--plot {tmp}/missing/m.png: the folder {tmp}/missing does not exist"),
    (["-o", "{tmp}/missing/m.yaml"], "-o {tmp}/missing/m.yaml: the folder {tmp}/missing does not exist"),
], ids=["lag<0", "lag=0", "lag=1e6", "lag=nan", "plot-suffix", "plot-folder", "o-folder"])
def test_a_bad_option_is_refused_before_the_record_is_read(option, message, tmp_path, capsys):
    """The record does not exist: the refusal names the option, so the option was checked first."""
    import re

    option = [o.replace("{tmp}", str(tmp_path)) for o in option]
    err = refused([str(tmp_path / "missing.csv"), *option], capsys)
    assert re.search(message.replace("{tmp}", re.escape(str(tmp_path))), err), err
    assert "missing.csv" not in err and list(tmp_path.iterdir()) == []


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


def quiet_trace(path, acceleration: bool = True):
    """A trace of 2 s at 1 ms whose accelerometer never delivered (status bit 8 clear); without the
    accelerometer's columns, a trace of a service from before them."""
    import numpy as np

    from stiffness.data.trace_file import ACCELERATION, COLUMNS, TraceFile

    table = np.zeros((2000, len(COLUMNS)))
    table[:, COLUMNS.index("time_s")] = np.arange(2000) * 0.001
    table[:, COLUMNS.index("cycle")] = np.arange(1, 2001)
    table[:, COLUMNS.index("status_word")] = 1
    with TraceFile(path) as f:
        f.write(table)
    if not acceleration:
        lines = path.read_text().splitlines()
        keep = [k for k, c in enumerate(lines[0].split(",")) if c not in ACCELERATION]
        path.write_text("\n".join(",".join(row.split(",")[k] for k in keep) for row in lines) + "\n")
    return path


def test_a_trace_is_read_with_the_config_the_cut_ran_with_and_refused_without_acceleration(tmp_path, capsys):
    from plc_link.contract import Status
    from stiffness.dynamics.from_cut import ACCELEROMETER_OK

    assert ACCELEROMETER_OK == int(Status.ACCELEROMETER_OK)        # the trace's bit, spelt below the contract
    trace = quiet_trace(tmp_path / "cut.csv")
    assert "give --config SERVICE.yaml" in refused([str(trace)], capsys)
    config = str(ROOT / "config" / "hil" / "service.yaml")
    assert "never marked as arriving" in refused([str(trace), "--config", config], capsys)
    old = quiet_trace(tmp_path / "old.csv", acceleration=False)
    assert "its accelerometer columns are missing" in refused([str(old), "--config", config], capsys)


def test_a_compare_file_without_a_structure_the_service_takes_is_refused_naming_it(record, tmp_path, capsys):
    none = tmp_path / "none.yaml"
    none.write_text("dynamics: {enabled: true}\n")
    assert f"--compare {none}: no dynamics.structure in it" in refused([str(record), "--compare", str(none)], capsys)
    bad = tmp_path / "bad.yaml"
    bad.write_text("dynamics:\n  structure:\n    modes: [{hz: 10.0, damping: 0.03, direction: [0, 0, 0]}]\n")
    err = refused([str(record), "--compare", str(bad)], capsys)
    assert str(bad) in err and "dynamics.structure.modes" in err and "must not be zero" in err
