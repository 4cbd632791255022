"""The virtual CMM writes QIF 3 results (issue 39, item 3): what `stiffness.data.qif_write` writes validates
against the QIF 3.0 schema (tests/data/qif3) and reads back through the QIF reader with the same points; a broken
file does not validate; `hil circle --cmm part.qif` and `--cmm part.csv` of the same cut give the same points
and the same `part learn` model."""

from __future__ import annotations

import json
import re
import uuid

import numpy as np
import pytest

from hil.testing import ROTATIONAL, scaled_model_file
from stiffness.data.part_points import read_part
from stiffness.data.qif_part import read_qif, read_qif_part
from stiffness.data.qif_write import NominalCircle, write_qif_circle
from stiffness.errors import DataError
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import ROOT
from testlib.qif import qif3_schema, write_qif
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"


def _arc(radius: float = 39.0, n: int = 50) -> np.ndarray:
    """Points (mm) on a circle over 340 deg, in a plane tilted about x, 2 mm below a centre off the origin."""
    a = np.radians(np.linspace(10.0, 350.0, n))
    local = np.column_stack([radius * np.cos(a), radius * np.sin(a), np.zeros(n)])
    c, s = np.cos(0.2), np.sin(0.2)
    return local @ np.array([[1, 0, 0], [0, c, -s], [0, s, c]]).T + [12.34567, -8.0, -2.0]


def _written(path, internal: bool = True, radius: float = 39.0):
    normal = np.array([0.0, -np.sin(0.2), np.cos(0.2)])
    nominal = NominalCircle(np.array([12.3, -8.0, -2.0]), normal, 2 * radius, internal)
    return write_qif_circle(path, _arc(radius), nominal)


@pytest.fixture(scope="module")
def schema():
    return qif3_schema()


@pytest.mark.parametrize("internal", [True, False], ids=["hole", "boss"])
def test_the_written_file_validates_against_the_qif3_schema(tmp_path, schema, internal):
    path = _written(tmp_path / "part.qif", internal)
    reasons = [str(e.reason) for e in schema.iter_errors(path)]
    assert not reasons, reasons


BROKEN = {
    # a measured feature naming a feature item the file does not have: the schema's key references
    "unknown item": (("<FeatureItemId>3<", "<FeatureItemId>33<"), "FeatureItemIdKey"),
    # the point set without Compensated, which QIF 3 requires of every measured point set
    "no compensated": (("<Compensated>true</Compensated>", ""), "'t:Compensated'"),
    # a coordinate that is not a number
    "not a number": (("<Points>\n", "<Points>\nx "), "could not convert string to float: 'x'"),
    # two elements with one id
    "duplicate id": (('MeasuredPointSet id="6"', 'MeasuredPointSet id="5"'), "QIFIdUnique"),
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_validation_catches_a_broken_file(tmp_path, schema, case):
    (old, new), expect = BROKEN[case]
    path = _written(tmp_path / "part.qif")
    text = path.read_text()
    assert text.count(old) == 1
    path.write_text(text.replace(old, new))
    reasons = " / ".join(str(e.reason) for e in schema.iter_errors(path))
    assert expect in reasons, reasons


def test_what_the_writer_writes_the_reader_reads_back(tmp_path):
    pts = _arc()
    qif = read_qif(_written(tmp_path / "part.QIF"))
    (f,) = qif.features
    assert (f.name, f.type, f.compensated, f.internal, qif.unit) == ("CONTOUR", "Circle", True, True, "mm")
    assert np.array_equal(f.points_mm, np.round(pts, 4))              # 4 decimals, as the part CSV writes
    assert f.reported_diameter_mm == pytest.approx(78.0, abs=2e-4)     # the circle fitted to the points
    part, note, _ = read_qif_part(tmp_path / "part.QIF", 4.0, None)
    assert np.array_equal(part.points_mm, f.points_mm) and "points as measured" in note
    assert read_qif(_written(tmp_path / "boss.qif", internal=False)).features[0].internal is False


def test_the_same_points_give_the_same_bytes_and_others_another_qpid(tmp_path):
    """The writer derives the document's QPId from its content (a version 5 UUID), as the PLC library's
    generator gives the same bytes for the same input: a random one made every cut's file differ."""
    first, again = (_written(tmp_path / f"{k}.qif").read_bytes() for k in ("a", "b"))
    assert first == again
    other = _written(tmp_path / "c.qif", radius=39.001).read_bytes()
    qpid, other_qpid = (uuid.UUID(re.search(rb"<QPId>([^<]+)</QPId>", b).group(1).decode()) for b in (first, other))
    assert qpid.version == 5 and other_qpid != qpid


def test_probe_centres_in_the_standards_point_set_give_the_reported_diameter(tmp_path, capsys):
    """QIF 3.0 keeps a point set's points as one list of x y z triples, and Compensated and ProbeRadius on the
    set: they are read as the feature's (probe centres moved 1.5 mm outward in the hole)."""
    path = write_qif(tmp_path / "hole.qif", _arc(16.0, 24), compensated=False, probe_radius=1.5, diameter=35.0,
                     flat=True)
    assert main(["part", "features", str(path), "--json"]) == 0
    row = json.loads(capsys.readouterr().out)["features"][0]
    assert (row["points"], row["compensated"], row["reported_diameter_mm"]) == (24, False, 35.0)
    assert abs(row["diameter_mm"] - 35.0) < 0.005


def _not_triples(path):
    path.write_text(re.sub(r"(<Points>\S+) ", r"\1", path.read_text(), count=1))     # two numbers made one


@pytest.mark.parametrize("case, edit, expect", [
    ("count", {"count": 25}, "MeasuredPointSet 20: count '25' but 24 points"),
    ("triples", {}, "MeasuredPointSet 20: Points holds 71 numbers, not x y z triples"),
    ("not applicable", {"internal": None}, "says neither whether the feature is INTERNAL or EXTERNAL"),
    ("not applicable, a diameter neither side's", {"internal": None, "diameter": 32.0},
     "nor a Diameter that tells"),
])
def test_a_standard_point_set_that_does_not_add_up_is_refused(tmp_path, case, edit, expect):
    path = write_qif(tmp_path / "bad.qif", _arc(16.0, 24), compensated=False, probe_radius=1.5, flat=True, **edit)
    if case == "triples":
        _not_triples(path)
    with pytest.raises(DataError) as e:
        read_qif_part(path, 4.0, None)
    assert str(path) in str(e.value) and expect in str(e.value), str(e.value)


def _cut(tmp_path, part: str, trace: str) -> str:
    """`stiffcomp hil circle --lockstep --no-compensation --cmm PART --trace TRACE`: its stdout."""
    args = ["hil", "circle", "--lockstep", "--no-compensation", "--cmm", str(tmp_path / part),
            "--trace", str(tmp_path / trace)]
    assert main(args) == 0
    return part


@pytest.mark.hil
def test_hil_circle_writes_qif_that_validates_and_learns_as_the_csv_of_the_same_cut(tmp_path, schema, capsys):
    """In lock step the cut is the same every run: once written as a part CSV, once as QIF (its suffix in
    capitals). The QIF validates, `part features` and the reader see the CSV's points (so both are the same
    cut, and the first run's trace is the second's), and `part learn` on that trace learns the same model from
    either file, given the options the command printed for the QIF."""
    _cut(tmp_path, "part.csv", "trace.csv")
    capsys.readouterr()
    _cut(tmp_path, "part.QIF", "trace2.csv")
    out = capsys.readouterr().out
    options = re.search(r"part\.QIF \(QIF 3; `stiffcomp part` reads it with (.*)\)", out).group(1).split()
    assert not list(schema.iter_errors(tmp_path / "part.QIF"))
    csv = read_part(tmp_path / "part.csv")
    qif = read_qif_part(tmp_path / "part.QIF", csv.tool_radius_mm, csv.frame).part
    assert len(csv) > 300 and np.array_equal(qif.points_mm, csv.points_mm)
    assert main(["part", "features", str(tmp_path / "part.QIF"), "--json"]) == 0
    assert f'"points": {len(csv)}' in capsys.readouterr().out
    start = scaled_model_file(TRUTH, 0.6, tmp_path / "start.yaml", keys=ROTATIONAL)
    learn = ["part", "learn", str(start), str(tmp_path / "trace.csv")]
    assert main([*learn, str(tmp_path / "part.csv"), "-o", str(tmp_path / "csv.yaml")]) == 0
    assert main([*learn, str(tmp_path / "part.QIF"), "-o", str(tmp_path / "qif.yaml"), *options]) == 0
    csv_model, qif_model = (StiffnessModel.from_yaml(tmp_path / f"{k}.yaml") for k in ("csv", "qif"))
    assert not np.allclose(csv_model.theta, StiffnessModel.from_yaml(start).theta)      # it learned something
    assert np.allclose(csv_model.theta, qif_model.theta, rtol=1e-9, atol=0.0)
