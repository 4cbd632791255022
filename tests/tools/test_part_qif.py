"""A CMM's QIF 3 results file read as a part (issue 39, items 1 and 2): `stiffcomp part features` fits the
probe-compensated circle to the file's reported diameter, inches read as the same geometry in mm, the same
points as QIF and as a part CSV learn the same model, and each bad input is refused in one line (exit 2)."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
import yaml

from stiffness.data.part_points import read_part
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import ROOT
from testlib.part import TOOL_RADIUS_MM, synthetic_cut
from testlib.qif import write_qif
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"
HOLE_D, PROBE_R = 35.0, 1.5


def _ring(radius: float, n: int = 24) -> np.ndarray:
    """Points on a circle of ``radius`` (mm) over 300 deg, in a tilted plane away from the origin."""
    a = np.radians(np.linspace(10.0, 310.0, n))
    local = np.column_stack([radius * np.cos(a), radius * np.sin(a), np.zeros(n)])
    c, s = np.cos(0.3), np.sin(0.3)
    return local @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]]).T + [120.0, -40.0, 15.0]


def _features(capsys, path) -> list[dict]:
    assert main(["part", "features", str(path), "--json"]) == 0
    return json.loads(capsys.readouterr().out)["features"]


def test_probe_centres_in_a_hole_give_the_reported_diameter(tmp_path, capsys):
    path = write_qif(tmp_path / "hole.qif", _ring(HOLE_D / 2 - PROBE_R), compensated=False, probe_radius=PROBE_R,
                     diameter=HOLE_D)
    (f,) = _features(capsys, path)
    assert (f["name"], f["id"], f["type"], f["points"], f["compensated"], f["units"]) == \
        ("HOLE", "11", "Circle", 24, False, "mm")
    assert f["reported_diameter_mm"] == HOLE_D
    assert abs(f["diameter_mm"] - HOLE_D) < 0.005


def test_probe_centres_on_a_boss_move_inward(tmp_path, capsys):
    path = write_qif(tmp_path / "boss.QIF", _ring(HOLE_D / 2 + PROBE_R), compensated=False, probe_radius=PROBE_R,
                     diameter=HOLE_D, internal=False, name="BOSS")
    assert abs(_features(capsys, path)[0]["diameter_mm"] - HOLE_D) < 0.005


def test_inches_give_the_same_geometry_in_mm(tmp_path, capsys):
    from stiffness.data.qif_part import read_qif_part

    pts = _ring(HOLE_D / 2 - PROBE_R)
    mm = write_qif(tmp_path / "mm.qif", pts, compensated=False, probe_radius=PROBE_R, diameter=HOLE_D)
    inch = write_qif(tmp_path / "in.qif", pts / 25.4, unit="inch", compensated=False, probe_radius=PROBE_R / 25.4,
                     diameter=HOLE_D / 25.4)
    (f,) = _features(capsys, inch)
    assert f["units"] == "inch" and abs(f["diameter_mm"] - HOLE_D) < 0.005
    assert abs(f["reported_diameter_mm"] - HOLE_D) < 1e-6
    a, note, _ = read_qif_part(mm, 4.0, None)
    b = read_qif_part(inch, 4.0, None).part
    assert np.allclose(a.points_mm, b.points_mm, atol=1e-6)
    assert "outward" in note and np.allclose(np.linalg.norm(a.points_mm - pts, axis=1), PROBE_R)


def test_a_range_or_a_single_point_of_a_point_set_reads_those_points(tmp_path):
    from stiffness.data.qif_part import read_qif, read_qif_part

    pts = _ring(HOLE_D / 2)
    part = read_qif_part(write_qif(tmp_path / "r.qif", pts, point_range=(3, 10)), 4.0, None).part
    assert np.allclose(part.points_mm, pts[2:10])
    one = read_qif(write_qif(tmp_path / "s.qif", pts, point_range=(5, 5))).features[0]
    assert np.allclose(one.points_mm, pts[4:5]) and one.labels == ["20:5"]


def test_results_and_feature_pick_by_number_and_id(tmp_path, capsys):
    from stiffness.data.qif_part import read_qif, read_qif_part

    pts = _ring(HOLE_D / 2)
    path = write_qif(tmp_path / "two.qif", pts, results=2)
    second = read_qif(path, 2)
    assert second.results == 2 and [f.id for f in second.features] == ["31"]
    part = read_qif_part(path, 4.0, None, "31", 2).part
    assert np.allclose(part.points_mm, pts) and part.title == "QIF feature HOLE"
    assert main(["part", "features", str(path), "--results", "3"]) == 2
    assert "--results 3: the file holds 2 MeasurementResults" in capsys.readouterr().err


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    w = tmp_path_factory.mktemp("qif_learn")
    truth = StiffnessModel.from_yaml(TRUTH)
    c = synthetic_cut(truth, w, "A", points=90)
    start = truth.copy()
    start.theta = 0.7 * start.theta
    start.to_yaml(w / "start.yaml")
    return w, c


def _learned(path) -> list:
    return yaml.safe_load(path.read_text())


def test_qif_and_csv_of_the_same_points_learn_the_same_model(cut, capsys):
    w, c = cut
    part = read_part(c.part)
    write_qif(w / "A.qif", part.points_mm, name="CONTOUR")
    frame = [f"{v:.4f}" for v in c.frame.xyz_mm] + [f"{v:.6g}" for v in c.frame.rpy_deg]   # as the CSV has them
    args = ["part", "learn", str(w / "start.yaml"), str(c.trace)]
    assert main([*args, str(c.part), "-o", str(w / "csv.yaml"), "--force"]) == 0
    assert main([*args, str(w / "A.qif"), "-o", str(w / "qif.yaml"), "--force", "--tool-radius-mm",
                 str(TOOL_RADIUS_MM), "--part-frame", *frame]) == 0
    assert f"note: {w / 'A.qif'}: feature CONTOUR: points as measured" in capsys.readouterr().err
    csv_model, qif_model = StiffnessModel.from_yaml(w / "csv.yaml"), StiffnessModel.from_yaml(w / "qif.yaml")
    assert not np.allclose(csv_model.theta, StiffnessModel.from_yaml(w / "start.yaml").theta)
    assert np.allclose(csv_model.theta, qif_model.theta, rtol=1e-6, atol=0.0)


BOMB = ('<?xml version="1.0"?>\n<!DOCTYPE lolz [<!ENTITY lol "lol">'
        + "".join(f'<!ENTITY lol{k + 1} "{("&lol" + (str(k) if k else "") + ";") * 10}">' for k in range(9))
        + ']>\n<QIFDocument xmlns="http://qifstandards.org/xsd/qif3" versionQIF="3.0.0">&lol9;</QIFDocument>\n')
EXTERNAL = ('<?xml version="1.0"?>\n<!DOCTYPE d [<!ENTITY x SYSTEM "file:///etc/passwd">]>\n'
            '<QIFDocument xmlns="http://qifstandards.org/xsd/qif3" versionQIF="3.0.0">&x;</QIFDocument>\n')


def _bad(tmp_path, case) -> tuple:
    ring = _ring(HOLE_D / 2)
    p = tmp_path / "bad.qif"
    if case == "not xml":
        p.write_text("point,x_mm,y_mm,z_mm\n1,2,3,4\n")
    elif case == "not qif":
        p.write_text('<?xml version="1.0"?>\n<Part><Point/></Part>\n')
    elif case == "version":
        write_qif(p, ring, version="2.0.0")
    elif case == "no points":
        write_qif(p, ring, point_set_ref=None)
    elif case == "unresolved":
        write_qif(p, ring, point_set_ref="77")
    elif case == "unit":
        write_qif(p, ring, unit="furlong")
    elif case == "binary":
        write_qif(p, ring, binary=True)
    elif case == "bomb":
        p.write_text(BOMB)
    elif case == "external":
        p.write_text(EXTERNAL)
    elif case == "unknown feature":
        write_qif(p, ring)
        return p, ["--feature", "NOPE"], "the file has: HOLE (id 11"
    elif case == "several results":
        write_qif(p, ring, results=2)
        return p, [], "pick one with --results N: 1 (id 10), 2 (id 30)"
    expect = {"not xml": "not well-formed XML", "not qif": "not QIF: the root element is 'Part'",
              "version": "versionQIF '2.0.0'", "no points": "no measured points", "unresolved": "WholePointSetId '77' does not resolve",
              "unit": "UnitName 'furlong'", "binary": "CombinedPointsBinary", "bomb": "refused: the XML declares",
              "external": "refused: the XML declares"}[case]
    return p, [], expect


LEFT_OUT = ("unresolved", "binary")      # of one feature, not of the file: `part features` names it, left out
CASES = ["not xml", "not qif", "version", "no points", "unresolved", "unit", "binary", "bomb", "external",
         "unknown feature", "several results"]


@pytest.mark.parametrize("case", CASES)
def test_bad_qif_is_refused_in_one_line(tmp_path, capsys, case):
    path, extra, expect = _bad(tmp_path, case)
    t0 = time.monotonic()
    from stiffness.data.qif_part import read_qif_part
    from stiffness.errors import DataError

    with pytest.raises(DataError) as e:
        read_qif_part(path, 4.0, None, extra[1] if extra else None)
    assert time.monotonic() - t0 < 1.0
    assert str(path) in str(e.value) and expect in str(e.value) and "\n" not in str(e.value), str(e.value)
    if case in ("no points", "unknown feature"):           # `part features` lists a feature without points
        return
    code = main(["part", "features", str(path)])
    out, err = capsys.readouterr()
    if case in LEFT_OUT:                                   # the file reads; the feature is named, left out
        assert code == 0 and not err and f"{path}: feature HOLE (id 11, Circle) left out: " in out, out
        assert expect in out.splitlines()[-1]
    else:
        assert code == 2 and not out and len(err.strip().splitlines()) == 1 and expect in err, err


def test_qif_options_without_a_qif_part_are_refused(tmp_path, capsys):
    assert main(["part", "compare", str(tmp_path / "m.yaml"), str(tmp_path / "t.csv"), str(tmp_path / "p.csv"),
                 "--feature", "HOLE"]) == 2
    assert "--feature: only for a .qif part" in capsys.readouterr().err
    assert main(["part", "compare", str(tmp_path / "m.yaml"), str(tmp_path / "t.csv"), str(tmp_path / "p.qif")]) == 2
    assert "needs --tool-radius-mm" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []
