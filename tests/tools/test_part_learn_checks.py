"""`stiffcomp part learn` does not learn in silence from parts that do not fit the model (issue 35, item 4).

A part whose part_frame is 2 mm off, a tool radius of 5 mm for a 4 mm cutter, parts that determine nothing
better than the prior, and an input model that already held a negative compliance: each is named with its
likely cause in one line on stderr (exit 2) and nothing is written, unless --force, which writes it. A sound
part still learns and writes; so does one measured with exactly the noise the model states.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from stiffness.data.part_points import read_part
from stiffness.data.trace_file import read_trace
from stiffness.model.prior import Prior, covariance_entry
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.part.learn import learn
from stiffness.part.rows import read_against
from stiffness.part.sanity import residual_exceeds
from testlib.common import ROOT
from testlib.part import synthetic_cut
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"
SHIFT_MM = 2.0


@pytest.fixture(scope="module")
def cut(tmp_path_factory):
    """A part cut by the truth (probe noise 2 um), a start model 40 % too stiff in rotation, and the variants."""
    w = tmp_path_factory.mktemp("learn_checks")
    truth = StiffnessModel.from_yaml(TRUTH)
    c = synthetic_cut(truth, w, "A")
    start = truth.copy()
    start.theta = np.where([lab.split(".")[-1].startswith("r") for lab in start.param_labels()],
                           0.6 * start.theta, start.theta)
    start.to_yaml(w / "start.yaml")
    text = c.part.read_text()
    x = float(re.search(r"xyz_mm: \[([^,]+),", text).group(1))
    (w / "frame_off.csv").write_text(text.replace(f"xyz_mm: [{x:.4f},", f"xyz_mm: [{x + SHIFT_MM:.4f},"))
    (w / "radius5.csv").write_text(text.replace("# tool_radius_mm: 4\n", "# tool_radius_mm: 5\n"))
    (w / "radius3.7.csv").write_text(text.replace("# tool_radius_mm: 4\n", "# tool_radius_mm: 3.7\n"))
    assert (w / "frame_off.csv").read_text() != text and (w / "radius5.csv").read_text() != text
    known = truth.copy()               # a prior far tighter than any part: 0.01 % of each value
    known.covariance = covariance_entry(known, np.diag((1e-4 * known.theta) ** 2), "a campaign of a million rows")
    known.to_yaml(w / "known.yaml")
    negative = truth.copy()
    k = negative.param_labels().index("joint_spring@joint2.x_m_per_N")
    th = negative.theta.copy()
    th[k] = -th[k]
    negative.theta = th
    negative.to_yaml(w / "negative.yaml")
    noisy = synthetic_cut(truth, w, "N", noise_um=1000 * truth.noise["position_mm"], seed=3)
    return w, c, noisy


def _learn(capsys, model, trace, part, out, *extra):
    rc = main(["part", "learn", str(model), str(trace), str(part), "-o", str(out), *extra])
    o, e = capsys.readouterr()
    return rc, o, e


def _refused_then_forced(capsys, w, c, model, part, name) -> tuple[str, str]:
    """Exit 2, one line on stderr naming the output, nothing written (nor the report's folder); with --force,
    exit 0 and the model written. Returns (stdout, the stderr line) of the refusal."""
    out, report = w / f"{name}_learned.yaml", w / f"{name}_report"
    rc, o, e = _learn(capsys, model, c.trace, part, out, "--report", str(report))
    lines = e.strip().splitlines()
    assert rc == 2 and lines[-1].startswith(f"stiffcomp part: error: {out}: not written: "), e
    assert lines[-1].endswith("; --force writes it") and "Traceback" not in e
    assert not out.exists() and not report.exists()
    rc, o2, e2 = _learn(capsys, model, c.trace, part, out, "--force")
    assert rc == 0 and out.exists(), e2
    assert StiffnessModel.from_yaml(out).param_labels() == StiffnessModel.from_yaml(model).param_labels()
    assert f"written: {out} (--force: despite the problem(s) above)" in o2
    return o, lines[-1]


def test_a_sound_part_learns_and_is_written(cut, capsys):
    w, c, _ = cut
    rc, o, e = _learn(capsys, w / "start.yaml", c.trace, c.part, w / "sound.yaml")
    assert rc == 0 and (w / "sound.yaml").exists(), e
    assert "problem:" not in o and f"written: {w / 'sound.yaml'}\n" in o


def test_a_part_measured_with_the_stated_noise_still_learns(cut, capsys):
    """The threshold is the stated noise's own chi-square tail: a part whose probe noise is exactly
    noise.position_mm is not refused."""
    w, _, noisy = cut
    rc, o, e = _learn(capsys, w / "start.yaml", noisy.trace, noisy.part, w / "noisy.yaml", "--json")
    assert rc == 0 and (w / "noisy.yaml").exists(), e
    assert '"problems": []' in o


def test_a_part_2_mm_off_its_frame_is_named_with_the_shift_and_not_written(cut, capsys):
    w, c, _ = cut
    o, line = _refused_then_forced(capsys, w, c, w / "start.yaml", w / "frame_off.csv", "frame_off")
    assert "the parts do not fit this model" in line and "part_frame" in line and "--best-fit" in line
    shift = re.search(r"part 1 \(([-+.\d]+), ([-+.\d]+), ([-+.\d]+)\) mm", line)
    assert shift, line
    assert np.allclose([float(v) for v in shift.groups()], [SHIFT_MM, 0.0, 0.0], atol=0.1), line
    assert "problem: the parts leave RMS" in o


def test_a_wrong_tool_radius_is_named_and_not_written(cut, capsys):
    w, c, _ = cut
    _, line = _refused_then_forced(capsys, w, c, w / "start.yaml", w / "radius5.csv", "radius5")
    pulled, allowed = (float(v) for v in re.search(r"pull the model ([\d.]+) prior sigma .* allows ([\d.]+)",
                                                    line).groups())
    assert pulled > 2 * allowed and "tool_radius_mm" in line


def test_parts_that_determine_nothing_are_named_and_not_written(cut, capsys):
    w, c, _ = cut
    o, line = _refused_then_forced(capsys, w, c, w / "known.yaml", c.part, "known")
    assert "nothing was learned" in line and "a campaign of a million rows" in line
    assert "determine 0 combination(s)" in o


def test_an_input_with_a_negative_compliance_is_named_and_the_data_not_blamed(cut, capsys):
    w, c, _ = cut
    o, line = _refused_then_forced(capsys, w, c, w / "negative.yaml", c.part, "negative")
    assert "negative compliance(s) (joint_spring@joint2.x_m_per_N)" in line and "--nonnegative" in line
    warning = next(x for x in o.splitlines() if "joint_spring@joint2.x_m_per_N" in x and x.startswith("warning:"))
    assert "the starting model already held them below zero" in warning
    assert "the data push them below zero" not in warning


def test_a_radius_the_compliances_half_absorb_is_given_back_by_one_distance_along_the_normals(cut):
    """A tool radius of 3.7 mm for the 4 mm cutter puts every point 0.3 mm beyond the wall: learning takes most of
    it into the compliances and leaves a little more than the noise explains (0.041 mm against 0.038). Learned
    once more with one distance along every normal (`learn.Offsets`), the part fits within the noise and the
    distance has the radius's sign; the sound part is not learned again."""
    w, c, _ = cut
    start = StiffnessModel.from_yaml(w / "start.yaml")
    prior = Prior.catalogue(start, 0.5)

    def learned(part):
        return learn(start, [read_against(read_part(part), read_trace(c.trace), start.robot)], prior)

    sound, off = learned(c.part), learned(w / "radius3.7.csv")
    assert not residual_exceeds(sound, start) and sound.offsets is None
    assert residual_exceeds(off, start) and off.offsets is not None
    assert off.offsets.after_mm < 0.1 * off.after_mm and off.offsets.offset_mm["part"] > 0.0, off.offsets
    assert off.problems and "tool_radius_mm" in off.problems[0]
