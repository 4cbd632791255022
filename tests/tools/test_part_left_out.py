"""Every `stiffcomp part` command names the points it leaves out, in its text and its JSON, and its figures say
whether they hold them (issue 35, item 5): a point 2.7 mm off the contour, which the robust fit of `learn` and
`diagnose` judges a gross error; the points a closed contour's entry and exit both passed, which `compare`
cannot place."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hil.testing import ROTATIONAL, scaled_model_file
from stiffness.data.part_points import read_part, write_part
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import ROOT
from testlib.part import synthetic_cut
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"
OFF_MM = 2.7
K = 60


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    """A cut by the truth, its part, the part with point K moved OFF_MM outward, and a model 40 % too stiff."""
    folder = tmp_path_factory.mktemp("left_out")
    c = synthetic_cut(StiffnessModel.from_yaml(TRUTH), folder)
    part = read_part(c.part)
    pts = part.points_mm.copy()
    pts[K, :2] += OFF_MM * pts[K, :2] / np.linalg.norm(pts[K, :2])     # the part frame is at the circle's centre
    bad = write_part(folder / "bad.csv", pts, 4.0, c.frame)
    start = scaled_model_file(TRUTH, 0.6, folder / "start.yaml", keys=ROTATIONAL)
    return c, bad, int(part.lines[K]), start, folder


def _run(capsys, *argv) -> str:
    assert main(["part", *map(str, argv)]) == 0
    return capsys.readouterr().out


def test_learn_names_the_point_its_fit_left_out_and_gives_the_rms_with_and_without_it(cut, capsys):
    c, bad, line, start, folder = cut
    clean = json.loads(_run(capsys, "learn", start, c.trace, c.part, "-o", folder / "clean.yaml", "--json"))
    got = json.loads(_run(capsys, "learn", start, c.trace, bad, "-o", folder / "l.yaml", "--json"))
    assert clean["left_out"] == [] and clean["points"] == 180
    assert [(x["part"], x["line"], x["why"]) for x in got["left_out"]] == [(str(bad), line, "gross_error")]
    assert got["left_out"][0]["residual_mm"] == pytest.approx(OFF_MM, abs=0.05) and got["points"] == 179
    # over the points kept the part teaches what the clean one does; with the point the RMS is the point's
    assert got["rms_after_mm"] == pytest.approx(clean["rms_after_mm"], abs=0.001)
    assert got["rms_after_with_left_out_mm"] == pytest.approx(OFF_MM / np.sqrt(180), rel=0.1)
    text = _run(capsys, "learn", start, c.trace, bad, "-o", folder / "l.yaml")
    assert "179 points (1 left out, named below)" in text and "over the 179 points kept: RMS" in text
    assert f"with the 1 the fit left out: {got['rms_before_with_left_out_mm']:.4f} mm before, " \
           f"{got['rms_after_with_left_out_mm']:.4f} mm after" in text
    assert f"1 point(s) left out: the robust fit judged them gross errors: {bad} line(s) {line} (residual +2.6" in text


def test_diagnose_names_the_point_its_fit_left_out_in_its_text_too(cut, capsys):
    c, bad, line, start, _ = cut
    got = json.loads(_run(capsys, "diagnose", start, c.trace, bad, "--json"))
    assert [(x["line"], x["why"]) for x in got["left_out"]] == [(line, "gross_error")]
    assert got["rms_kept_mm"] < 0.01 and got["rms_with_left_out_mm"] > 0.15
    text = _run(capsys, "diagnose", start, c.trace, bad)
    assert f"{got['rms_kept_mm']:.4f} mm along the normal over the 179 points kept " \
           f"({got['rms_with_left_out_mm']:.4f} mm with the 1 the fit left out)" in text
    assert f"1 point(s) left out: the robust fit judged them gross errors: {bad} line(s) {line}" in text


def test_compare_names_the_points_it_cannot_place_by_line(cut, capsys):
    """With no mask the closed circle's entry and exit both passed the points at its start."""
    _, _, _, start, folder = cut
    c = synthetic_cut(StiffnessModel.from_yaml(TRUTH), folder, "overlap", mask_deg=0.0, points=360)
    got = json.loads(_run(capsys, "compare", start, c.trace, c.part, "--json"))
    lines = [x["line"] for x in got["left_out"]]
    assert 0 < len(lines) == got["left_out_count"] < 40 and {x["why"] for x in got["left_out"]} == {"passed_twice"}
    assert got["points"] + len(lines) == 360
    text = _run(capsys, "compare", start, c.trace, c.part)
    assert f"{got['points']} points of 360 ({len(lines)} left out, named below; every figure is over the " \
           f"{got['points']} used)" in text
    named = [t for t in text.splitlines() if t.startswith(f"{len(lines)} point(s) left out: the tool passed them")]
    assert len(named) == 1 and f"{c.part} line(s) " in named[0]
    assert all(str(v) in named[0] for v in (min(lines), max(lines)))
