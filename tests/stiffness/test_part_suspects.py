"""A part that does not lie where its trace's tool passed is refused naming every plausible cause with its
evidence, the likeliest first (issue 45, item 4): the diameter given as the radius, or a radius in inches,
names the radius (not the frame); a frame shifted far off names the frame, with the best fit's shift."""

from __future__ import annotations

import re

import numpy as np
import pytest

from stiffness.data.part_points import read_part, write_part
from stiffness.data.trace_file import read_trace
from stiffness.errors import DataError
from stiffness.kinematics.robot import PoseConfig
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.part.rows import read_against
from testlib.common import ROOT
from testlib.part import synthetic_cut
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"
RADIUS_MM = 4.0                 # the synthetic cut's cutter


@pytest.fixture(scope="module")
def truth() -> StiffnessModel:
    return StiffnessModel.from_yaml(TRUTH)


@pytest.fixture(scope="module")
def cut(truth, tmp_path_factory):
    return synthetic_cut(truth, tmp_path_factory.mktemp("suspects"))


def refusal(cut, truth, path) -> str:
    with pytest.raises(DataError) as e:
        read_against(read_part(path), read_trace(cut.trace), truth.robot)
    return str(e.value)


def causes(text: str) -> list[str]:
    """The numbered causes of a refusal, in its order."""
    return re.findall(r"\(\d\) ([^;:]+)", text.split("Likely causes, likeliest first: ")[1])


@pytest.mark.parametrize("given, hint", [(2 * RADIUS_MM, "8 mm is the diameter? a radius of 4 mm"), (RADIUS_MM / 25.4, "inches? 0.15748 in is 4 mm, a radius that puts")])
def test_a_diameter_or_an_inch_radius_names_the_radius_first(cut, truth, tmp_path, given, hint):
    part = read_part(cut.part)
    path = write_part(tmp_path / "wrong_radius.csv", part.points_mm, given, cut.frame)
    text = refusal(cut, truth, path)
    assert causes(text)[0] == "the tool radius" and hint in text, text
    assert "% of the points on the contour" in text                   # the evidence for it
    assert "the part_frame: unlikely" in text


@pytest.mark.parametrize("shift_mm, refusal_starts", [(6.0, "point(s) are not on the contour"),
                                                     (12.0, "never passes the measured contour")])
def test_a_frame_far_off_names_the_frame_with_the_fits_shift(cut, truth, tmp_path, shift_mm, refusal_starts):
    """Shifted across the circle's plane: the points lie r - shift to r + shift from the path, no one distance;
    a best fit of the frame finds the shift. 6 mm leaves some points on the contour (refused by line), 12 mm
    most off it."""
    part = read_part(cut.part)
    off = PoseConfig(xyz_mm=list(np.add(cut.frame.xyz_mm, [0.0, shift_mm, 0.0])), rpy_deg=cut.frame.rpy_deg)
    path = write_part(tmp_path / "frame_off.csv", part.points_mm, RADIUS_MM, off)
    text = refusal(cut, truth, path)
    assert refusal_starts in text.splitlines()[0]
    assert causes(text)[0] == "the part_frame", text
    shift = float(re.search(r"a best fit moves it ([0-9.]+) mm", text).group(1))
    assert shift == pytest.approx(shift_mm, abs=0.5)
    assert "the tool radius: unlikely alone" in text


@pytest.mark.parametrize("given, words", [(2 * RADIUS_MM, ("tool_radius_mm = 8 mm", "the diameter? a radius of 4 mm")),
                                          (RADIUS_MM / 25.4, ("tool_radius_mm = 0.15748 mm", "inches? 0.15748 in"))])
def test_part_learn_names_the_radius_given_as_the_diameter_or_in_inches(cut, truth, tmp_path, capsys, given, words):
    part = read_part(cut.part)
    path = write_part(tmp_path / "wrong_radius.csv", part.points_mm, given, cut.frame)
    rc = main(["part", "learn", str(TRUTH), str(cut.trace), str(path), "-o", str(tmp_path / "out.yaml")])
    err = capsys.readouterr().err
    assert rc == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    assert "(1) the tool radius" in err and all(w in err for w in words), err
    assert not (tmp_path / "out.yaml").exists()


def test_another_cuts_contour_is_named_with_its_size_against_the_paths(cut, truth, tmp_path):
    """The points of a larger contour (another cut), the radius right: every point some 4 mm further off than
    the radius says, all round. The points alone cannot tell that from a wrong radius, so both are named, the
    other cut with the two sizes as its evidence: the contour's span and the path's with the tool."""
    part = read_part(cut.part)
    centre = part.points_mm.mean(axis=0)
    grown = centre + (part.points_mm - centre) * 1.12
    path = write_part(tmp_path / "another_cut.csv", grown, RADIUS_MM, cut.frame)
    text = refusal(cut, truth, path)
    found = causes(text)
    assert found[0] == "the tool radius" and found[1].startswith("a file of another cut, whose contour lies +"), text
    off = float(re.search(r"whose contour lies \+([0-9.]+) mm off this one all round", text).group(1))
    spans = re.search(r"the contour spans ([0-9.]+) mm, the tool's path with the tool ([0-9.]+) mm", text)
    contour, path_span = float(spans.group(1)), float(spans.group(2))
    assert contour == pytest.approx(float(np.max(np.ptp(grown, axis=0))), abs=0.05), text
    assert contour - path_span == pytest.approx(2 * off, rel=0.25), text       # larger all round, both sides
