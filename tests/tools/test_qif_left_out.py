"""A QIF results file as CMM software writes it (issue 44, item 3): a feature whose points cannot be read (a
reference that does not resolve, a set without points, a form not read) is named and left out with the reason,
the file's other features still read, `--feature` picks a good one, and every part command says which it left
out; `Point/XYZ` directly under a set reads; messages name the elements as the file has them."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stiffness.data.part_points import read_part
from stiffness.data.qif_part import read_qif, read_qif_part
from stiffness.errors import DataError
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import ROOT
from testlib.part import TOOL_RADIUS_MM, synthetic_cut
from testlib.qif import OTHER_FORMS, write_qif
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"
REASONS = {
    "unresolved": "WholePointSetId '99' does not resolve to a MeasuredPointSet",
    "no points": "MeasuredPointSet 70: no points: neither Points nor Point/XYZ",
    "binary": "MeasuredPointSet 70: binary points (BinaryPoints) are not read; export the points as text (Points)",
    "compensations": "MeasuredPointSet 70: Compensations (one value per point) is not read",
    "coordinate system": "MeasuredPointSet 70: its points are in another coordinate system (CoordinateSystemId 3)",
}


def _ring(n: int = 24) -> np.ndarray:
    a = np.radians(np.linspace(10.0, 310.0, n))
    return np.column_stack([17.5 * np.cos(a) + 120.0, 17.5 * np.sin(a) - 40.0, np.full(n, 15.0)])


@pytest.mark.parametrize("form", [f for f in OTHER_FORMS if f != "point/xyz"])     # the forms not read
def test_a_feature_that_cannot_be_read_is_left_out_and_named(tmp_path, capsys, form):
    path = write_qif(tmp_path / "two.qif", _ring(), others=[("BAD", form)])
    qif = read_qif(path)
    assert [f.name for f in qif.features] == ["HOLE"] and np.allclose(qif.features[0].points_mm, _ring())
    (left,) = qif.left_out
    assert (left.name, left.id, left.type) == ("BAD", "60", "Circle") and left.reason.startswith(REASONS[form])
    part, _, left_out = read_qif_part(path, 4.0, None)            # the only feature that reads, without --feature
    assert np.allclose(part.points_mm, _ring()) and left_out == [left]
    assert np.allclose(read_qif_part(path, 4.0, None, "HOLE").part.points_mm, _ring())
    with pytest.raises(DataError) as e:
        read_qif_part(path, 4.0, None, "BAD")
    assert str(e.value) == f"{path}: --feature BAD: feature BAD (id 60, Circle) left out: {left.reason}"
    assert main(["part", "features", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert [r["name"] for r in out["features"]] == ["HOLE"]
    assert out["left_out"] == [{"name": "BAD", "id": "60", "type": "Circle", "reason": left.reason}]
    assert main(["part", "features", str(path)]) == 0
    assert capsys.readouterr().out.splitlines()[-1] == f"{path}: feature BAD (id 60, Circle) left out: {left.reason}"


def test_the_only_feature_left_out_is_named_not_a_traceback(tmp_path):
    path = write_qif(tmp_path / "one.qif", _ring(), point_set_ref=None, others=[("EMPTY", "no points")])
    with pytest.raises(DataError) as e:
        read_qif_part(path, 4.0, None)
    assert str(e.value) == (f"{path}: no measured points (PointList) in any measured feature that reads: HOLE (id "
                            "11, 0 points), EMPTY (id 60, left out); feature EMPTY (id 60, Circle) left out: "
                            "MeasuredPointSet 70: no points: neither Points nor Point/XYZ")


def test_point_xyz_directly_under_a_set_reads_as_its_points(tmp_path):
    path = write_qif(tmp_path / "xyz.qif", _ring(), flat=True, others=[("XYZ", "point/xyz")])
    qif = read_qif(path)
    hole, xyz = qif.features
    assert not qif.left_out and xyz.name == "XYZ" and np.array_equal(xyz.points_mm, hole.points_mm)
    assert xyz.labels == [f"70:{k}" for k in range(1, 25)]


@pytest.mark.parametrize("edit, reason", [
    (("<SinglePointSetId index=\"5\">", "<SinglePointSetId index=\"30\">"),
     "SinglePointSetId '20' index '30' is outside MeasuredPointSet 20's 24 points (from 1)"),
    (("<SinglePointSetId index=\"5\">", "<SinglePointSetId index=\"five\">"),
     "SinglePointSetId '20' index 'five' is not a whole number"),
    (("<SinglePointSetId index=\"5\">", "<RangePointSetId range=\"3 x\">"),
     "RangePointSetId '20' range '3 x' is not 'start end'"),
])
def test_a_reference_is_named_as_the_file_has_it(tmp_path, edit, reason):
    path = write_qif(tmp_path / "s.qif", _ring(), point_range=(5, 5))
    text = path.read_text()
    assert edit[0] in text
    text = text.replace(*edit)
    path.write_text(text.replace("</SinglePointSetId>", "</RangePointSetId>") if "Range" in edit[1] else text)
    (left,) = read_qif(path).left_out
    assert left.reason == reason


def test_a_file_without_results_names_the_results_element(tmp_path):
    path = write_qif(tmp_path / "plan.qif", _ring())
    path.write_text(path.read_text().replace("<Results>", "<Plans>").replace("</Results>", "</Plans>"))
    with pytest.raises(DataError) as e:
        read_qif(path)
    assert str(e.value) == f"{path}: no Results/MeasurementResultsSet/MeasurementResults: not a QIF results file"


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    w = tmp_path_factory.mktemp("qif_left_out")
    truth = StiffnessModel.from_yaml(TRUTH)
    c = synthetic_cut(truth, w, "A", points=90)
    start = truth.copy()
    start.theta = 0.7 * start.theta
    start.to_yaml(w / "start.yaml")
    write_qif(w / "A.qif", read_part(c.part).points_mm, name="CONTOUR", others=[("BAD", "unresolved")])
    frame = [f"{v:.4f}" for v in c.frame.xyz_mm] + [f"{v:.6g}" for v in c.frame.rpy_deg]
    return w, c, ["--tool-radius-mm", str(TOOL_RADIUS_MM), "--part-frame", *frame, "--feature", "CONTOUR"]


@pytest.mark.parametrize("command", ["compare", "learn", "diagnose"])
def test_every_part_command_says_which_features_it_left_out(cut, capsys, command):
    w, c, options = cut
    args = ["part", command, str(w / "start.yaml"), str(c.trace), str(w / "A.qif"), *options]
    if command == "learn":
        args += ["-o", str(w / "learned.yaml"), "--force"]
    line = f"{w / 'A.qif'}: feature BAD (id 60, Circle) left out: WholePointSetId '99' does not resolve to a " \
           "MeasuredPointSet"
    assert main([*args, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["left_out_features"] == [{"part": str(w / "A.qif"), "name": "BAD", "id": "60", "type": "Circle",
                                         "reason": "WholePointSetId '99' does not resolve to a MeasuredPointSet"}]
    assert line in out["notes"]
    assert main(args) == 0
    assert line in capsys.readouterr().out
