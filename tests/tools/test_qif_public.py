"""The QIF reader on public QIF 3.0 results files that CMM software wrote (issue 44, item 5; the files, their
source and licence: tests/data/qif_results/README.md). Each reads without a traceback and lists every measured
feature it holds, read or left out; where a file carries the measured points, what the reader derives from
them agrees with what the CMM software reported beside them (diameters, centres, positions, directions)."""

from __future__ import annotations

import hashlib
import json
import re
import xml.etree.ElementTree as ET

import numpy as np
import pytest

from stiffness.data.qif_part import fit_circle, read_qif, read_qif_part
from stiffness.errors import DataError
from testlib.common import ROOT
from tools.cli import main

HERE = ROOT / "tests" / "data" / "qif_results"
FILES = sorted(p.name for p in HERE.glob("*.QIF"))
POINTS = HERE / "QIF_PTS_SAMPLE.QIF"
NS = {"q": "http://qifstandards.org/xsd/qif3"}


def _reported(path) -> dict[str, ET.Element]:
    """Every measured feature of the file by id, as the CMM software wrote it (read here with plain ElementTree:
    the fixtures are trusted, and this is not the reader under test)."""
    root = ET.parse(path).getroot()
    return {fm.get("id"): fm for fm in root.iterfind(".//q:MeasuredFeatures/*", NS)}


def _vec(fm, path: str) -> np.ndarray:
    return np.array(fm.find(path, NS).text.split(), dtype=float)


def test_the_fixtures_are_the_published_files():
    text = (HERE / "README.md").read_text()
    listed = {name: digest for digest, name in re.findall(r"^    ([0-9a-f]{64})  (\S+)$", text, re.MULTILINE)}
    assert sorted(listed) == FILES and len(FILES) == 4
    for name in FILES:
        assert hashlib.sha256((HERE / name).read_bytes()).hexdigest() == listed[name], name


@pytest.mark.parametrize("name", FILES)
def test_each_file_reads_and_lists_every_measured_feature(name, capsys):
    path = HERE / name
    assert main(["part", "features", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    ids = [r["id"] for r in out["features"]] + [x["id"] for x in out["left_out"]]
    assert sorted(ids) == sorted(_reported(path))
    qif = read_qif(path)
    for f in qif.features:                     # the file's own Diameter, where it gives one, read in mm
        d = _reported(path)[f.id].find("q:Diameter", NS)
        assert f.reported_diameter_mm == (None if d is None else float(d.text))
    try:                                       # as a part: a feature, or one line saying why not
        read_qif_part(path, 4.0, None)
    except DataError as e:
        assert str(path) in str(e) and "\n" not in str(e)
    assert main(["part", "features", str(path)]) == 0          # the table too
    assert len(capsys.readouterr().out.splitlines()) == 1 + len(ids)


def test_the_point_cloud_leaves_out_the_feature_whose_reference_does_not_resolve():
    """POINT5 (id 828) references WholePointSetId 828, its own id: it is named with the reason, and the 13 others
    read, with the points their references take (RangePointSetId 3 8: 6, SinglePointSetId 1 and 2: 2)."""
    qif = read_qif(POINTS)
    (left,) = qif.left_out
    assert (left.name, left.id, left.type) == ("POINT5", "828", "Point")
    assert left.reason == "WholePointSetId '828' does not resolve to a MeasuredPointSet"
    counts = {f.name: len(f.points_mm) for f in qif.features}
    assert counts == {"DATUMA": 6, "DATUMB": 219, "DATUMC": 2, "CIRCLE1": 219, "CIRCLE2": 219, "POINT1": 1,
                      "POINT2": 1, "POINT3": 0, "POINT4": 1, "CYL_1": 18, "POINT6": 1, "CPLANE": 0, "3-D_LINE1": 0}
    assert {f.compensated for f in qif.features if len(f.points_mm)} == {False}
    with pytest.raises(DataError) as e:
        read_qif_part(POINTS, 4.0, None, "POINT5")
    assert str(e.value) == (f"{POINTS}: --feature POINT5: feature POINT5 (id 828, Point) left out: WholePointSetId "
                            "'828' does not resolve to a MeasuredPointSet")


def test_the_holes_read_as_the_cmm_reported_them(capsys):
    """CIRCLE1 and CIRCLE2 are INTERNAL: the reader moves the probe centres outward by ProbeRadius, and the
    circle through the moved points has the Diameter and Location the CMM software reported (to 1 um)."""
    assert main(["part", "features", str(POINTS), "--json"]) == 0
    rows = {r["name"]: r for r in json.loads(capsys.readouterr().out)["features"]}
    reported = _reported(POINTS)
    for name in ("CIRCLE1", "CIRCLE2"):
        assert abs(rows[name]["diameter_mm"] - rows[name]["reported_diameter_mm"]) < 1e-3
        part, note, left_out = read_qif_part(POINTS, 4.0, None, name)
        assert "probe centres moved 2.49978 mm outward (an internal feature)" in note
        assert [x.name for x in left_out] == ["POINT5"]
        centre, radius, _ = fit_circle(part.points_mm)
        assert np.linalg.norm(centre - _vec(reported[rows[name]["id"]], "q:Location")) < 1e-3
        assert abs(2 * radius - rows[name]["reported_diameter_mm"]) < 1e-3


def test_the_other_features_agree_with_what_the_cmm_reported():
    """Where the reader does not move the points (the definitions say NOT_APPLICABLE, or a plane, a line, a
    point), they are the probe's centres as the file has them: a circle through them is the reported one less
    ProbeRadius (DATUMB, and CYL_1's two rings), a measured point is its Location, a plane's centres lie
    ProbeRadius off the reported plane along its Normal, and a two-point line runs along the reported vector."""
    qif = read_qif(POINTS)
    by_name = {f.name: f for f in qif.features}
    reported = _reported(POINTS)
    r_probe = by_name["DATUMB"].probe_radius_mm
    assert r_probe == pytest.approx(2.49978271104)
    for name in ("DATUMB", "CYL_1"):
        f = by_name[name]
        assert f.internal is None and f.reported_diameter_mm is not None
        assert abs(2 * (fit_circle(f.points_mm)[1] + r_probe) - f.reported_diameter_mm) < 1e-3
    for name in ("POINT1", "POINT2", "POINT4", "POINT6"):
        f = by_name[name]
        assert np.allclose(f.points_mm[0], _vec(reported[f.id], "q:Location"), atol=1e-9)
    plane = by_name["DATUMA"]
    c = plane.points_mm.mean(axis=0)
    n = _vec(reported[plane.id], "q:Normal")
    assert np.linalg.norm(np.cross(np.linalg.svd(plane.points_mm - c)[2][2], n)) < 2e-4
    assert abs(abs((c - _vec(reported[plane.id], "q:Location")) @ n) - r_probe) < 5e-3
    line = by_name["DATUMC"]
    d = np.diff(line.points_mm, axis=0)[0]
    assert np.allclose(d / np.linalg.norm(d), _vec(reported[line.id], "q:Normal"), atol=1e-6)


def _mutants():
    """The point cloud with one element of its results removed, emptied or given a bad text, or an attribute of
    one dropped: what a CMM's export or a hand edit may break."""
    from hypothesis import strategies as st

    root = ET.parse(POINTS).getroot()
    n = sum(1 for _ in root.find("q:Results", NS).iter())
    return st.tuples(st.integers(0, n - 1), st.sampled_from(["remove", "empty", "x", "1 2", "-1", "drop attrs"]))


@pytest.fixture(scope="module")
def tree():
    ET.register_namespace("", NS["q"])
    return ET.parse(POINTS)


def test_a_broken_point_cloud_never_gives_a_traceback(tree, tmp_path_factory):
    """Whatever one element of the results becomes, the file reads (with features left out, named) or is
    refused in one line naming the file: never another exception."""
    import copy

    from hypothesis import HealthCheck, given, settings

    from stiffness.data.qif_part import feature_rows, pick, surface_points

    folder = tmp_path_factory.mktemp("mutants")

    @settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
    @given(_mutants())
    def check(mutation):
        k, how = mutation
        doc = copy.deepcopy(tree)
        results = doc.getroot().find("q:Results", NS)
        el = list(results.iter())[k]
        parent = next((p for p in results.iter() if el in list(p)), None)
        if how == "remove" and parent is not None:
            parent.remove(el)
        elif how == "drop attrs":
            el.attrib.clear()
        else:
            el.text = "" if how == "empty" else how
        path = folder / "mutant.qif"
        doc.write(path, xml_declaration=True, encoding="utf-8")
        try:
            qif = read_qif(path)
            feature_rows(qif)
            for f in qif.features + qif.left_out:          # what read_qif_part does with each, but one parse
                try:
                    surface_points(pick(qif, f.id), str(path))
                except DataError as e:
                    assert str(path) in str(e) and "\n" not in str(e)
        except DataError as e:
            assert str(path) in str(e) and "\n" not in str(e)

    check()


def test_a_circle_that_does_not_say_internal_or_external_is_told_by_its_reported_diameter(capsys):
    """DATUMB and CYL_1 (uncompensated, no InternalExternal): the reported diameter is the probe centres' circle
    plus the probe's diameter, a hole's; so moved outward, their surface's diameter is the reported one (it
    showed "-" and said nothing)."""
    from stiffness.data.qif_part import feature_rows, surface_points

    qif = read_qif(POINTS)
    rows = {r["name"]: r for r in feature_rows(qif)}
    for name in ("DATUMB", "CYL_1"):
        assert rows[name]["diameter_mm"] == pytest.approx(rows[name]["reported_diameter_mm"], abs=1e-3)
        f = next(f for f in qif.features if f.name == name)
        assert "its reported diameter" in surface_points(f, "x")[1] and "outward" in surface_points(f, "x")[1]


def test_a_circle_nothing_tells_the_side_of_says_so_on_its_row(tmp_path, capsys):
    """The same file without DATUMB's reported Diameter: the row says why it has no diameter."""
    from tools.cli import main

    text = POINTS.read_text()
    start = text.index('id="28"')                       # DATUMB's measurement
    d0 = text.index("<Diameter>", start)
    d1 = text.index("</Diameter>", d0) + len("</Diameter>")
    (tmp_path / "no_diameter.qif").write_text(text[:d0] + text[d1:])
    assert main(["part", "features", str(tmp_path / "no_diameter.qif")]) == 0
    row = next(line for line in capsys.readouterr().out.splitlines() if line.startswith("DATUMB"))
    assert "nor a Diameter that tells" in row and " - " in row, row


@pytest.mark.parametrize("internal", [True, False])
def test_the_side_by_diameter_recovers_a_hole_or_a_boss_within_a_quarter_probe_radius_of_noise(internal):
    from hypothesis import given, settings
    from hypothesis import strategies as st

    from stiffness.data.qif_part import side_by_diameter

    @settings(max_examples=200, deadline=None)
    @given(rc=st.floats(2.0, 500.0), rp=st.floats(0.1, 5.0), noise=st.floats(-0.25, 0.25))
    def check(rc, rp, noise):
        reported = 2 * (rc + (rp if internal else -rp) + noise * rp)
        assert side_by_diameter(rc, rp, reported) is internal
        assert side_by_diameter(rc, rp, None) is None

    check()
