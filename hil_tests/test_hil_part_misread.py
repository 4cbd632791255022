"""`part diagnose` never names an effect from a misread part (issue 50, item 1): a probe log or a CMM part whose
header or joints are wrong is refused, naming the file's suspect, before any physical effect is named; the same
files read right give no missing effect. The cut: the HIL in lock step, the robot with geometric errors cut with
the too-stiff model (as test_hil_probe.py's), its own probe and a virtual CMM of the same wall."""

from __future__ import annotations

import json
import math

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from hil.circle import cut
from hil.scenario import load_scenario
from testlib.hil import ROOT
from tools.cli import main

BUILT = ROOT / "examples" / "truth_geometric_errors.yaml"
START = ROOT / "examples" / "too_stiff_reference.yaml"


@pytest.fixture(scope="module")
def cell(tmp_path_factory):
    w = tmp_path_factory.mktemp("misread")
    cut(load_scenario(), BUILT, START, w / "cut", w / "cut.csv", w / "part.csv", probe_log=w / "probe.csv")
    return w


def _edit(src, dst, header=lambda line: line, joints=lambda q: q, approach=lambda d: d):
    """``src`` with each '#' line through ``header`` (a list back: the lines to write) and each touch's six
    joints (deg) through ``joints`` and its approach through ``approach``."""
    out, cols = [], None
    for line in src.read_text().splitlines():
        if line.startswith("#"):
            got = header(line)
            out += got if isinstance(got, list) else [got]
        elif cols is None:
            cols = line.split(",")
            out.append(line)
        else:
            v = line.split(",")
            if "q1_deg" in cols:
                v[1:7] = [f"{x:.6f}" for x in joints([float(x) for x in v[1:7]])]
                v[7:10] = [f"{x:.6f}" for x in approach([float(x) for x in v[7:10]])]
            out.append(",".join(v))
    dst.write_text("\n".join(out) + "\n")
    return dst


def _diagnose(capsys, w, part) -> tuple[int, str]:
    """`part diagnose`'s exit code and what it said (the JSON's verdict and message, or the refusal)."""
    try:
        code = main(["part", "diagnose", str(START), str(w / "cut.csv"), str(part), "--json"])
    except SystemExit as e:
        code = e.code
    out, err = capsys.readouterr()
    if code == 0:
        d = json.loads(out)
        return code, f"{d['verdict']}: {d['message']}"
    return code, err


def _swap(key, value):
    return lambda line: f"# {key}: {value}" if line.startswith(f"# {key}:") else line


WRONG = {
    "stylus radius 2 for 1.5": {"header": _swap("stylus_radius_mm", 2.0)},
    "tool radius 4.5 for 4": {"header": _swap("tool_radius_mm", 4.5)},
    "the tool radius given twice": {"header": lambda l: [l, "# tool_radius_mm: 5"] if l.startswith("# tool_r") else l},
    "the flange frame for the stylus's": {"header": _swap("probe_frame", "{xyz_mm: [250, 0, 0], rpy_deg: [0, 0, 0]}")},
    "joints in radians": {"joints": lambda q: [math.radians(x) for x in q]},
    "q1's sign flipped": {"joints": lambda q: [-q[0]] + q[1:]},
    "q3 offset by 90 deg": {"joints": lambda q: q[:2] + [q[2] + 90.0] + q[3:]},
}


NAMED = {   # the misreading, and the cause the refusal names first (`stiffness.part.probe_suspects`)
    "joints in radians": ({"joints": lambda q: [math.radians(x) for x in q]}, "(1) the joints are in radians"),
    "q1's sign flipped": ({"joints": lambda q: [-q[0], *q[1:]]}, "(1) q1_deg has the wrong sign"),
    "q3 offset by 90 deg": ({"joints": lambda q: [*q[:2], q[2] + 90.0, *q[3:]]},
                            "(1) q3_deg is +90.0 deg off the cut's joint 3"),
    "q1 at 400 deg": ({"joints": lambda q: [q[0] + 400.0, *q[1:]]}, "(1) q1_deg is +400.0 deg off the cut's joint 1"),
    "probe_frame in metres": ({"header": _swap("probe_frame", "{xyz_mm: [0, 0, 0.25], rpy_deg: [0, 0, 0]}")},
                              "(1) probe_frame's xyz_mm [0, 0, 0.25] is in metres"),
    "the flange frame for the stylus's": ({"header": _swap("probe_frame", "{xyz_mm: [250, 0, 0], rpy_deg: [0, 0, 0]}")},
                                          "(1) probe_frame's xyz_mm [250, 0, 0] puts the stylus off the flange's z axis"),
    "every approach reversed": ({"approach": lambda d: [-x for x in d]}, "(1) every approach is reversed"),
    "the tool's diameter as its radius": ({"header": _swap("tool_radius_mm", 8)},
                                          "tool_radius_mm = 8 is the cutter's diameter? "),
}


@pytest.mark.parametrize("case", sorted(NAMED))
def test_a_misread_probe_log_is_refused_naming_the_misreading_first(cell, tmp_path, case):
    """Each once read as a stylus radius that does not fit, touches that do not belong, or (metres) learned."""
    from stiffness.data.probe_log import read_probe
    from stiffness.data.trace_file import read_trace
    from stiffness.errors import DataError
    from stiffness.model.stiffness_model import StiffnessModel
    from stiffness.part.probe import read_probe_against

    edit, cause = NAMED[case]
    log = _edit(cell / "probe.csv", tmp_path / "probe.csv", **edit)
    with pytest.raises(DataError) as e:
        read_probe_against(read_probe(log), read_trace(cell / "cut.csv"), StiffnessModel.from_yaml(START).robot)
    assert cause in str(e.value) and "stylus_radius_mm = " not in str(e.value), str(e.value)


def test_the_probe_read_right_names_no_effect(cell, capsys):
    code, said = _diagnose(capsys, cell, cell / "probe.csv")
    assert code == 0 and said.startswith("no_missing_effect"), said


@pytest.mark.parametrize("case", sorted(WRONG))
def test_a_misread_probe_log_names_no_effect_and_never_advises_a_part_frame(cell, capsys, tmp_path, case):
    code, said = _diagnose(capsys, cell, _edit(cell / "probe.csv", tmp_path / "probe.csv", **WRONG[case]))
    assert code != 0 and "missing_effect" not in said, said
    assert "probe.csv" in said
    assert "--best-fit" not in said and "part_frame" not in said, said     # both refused for a probe log


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(off=st.floats(0.3, 3.0), which=st.sampled_from(["stylus_radius_mm", "tool_radius_mm"]),
       sign=st.sampled_from([-1.0, 1.0]))
@example(off=0.3, which="stylus_radius_mm", sign=1.0)     # the compliances absorb most of it (`learn.Offsets`)
def test_a_radius_off_by_any_amount_is_refused_before_an_effect_is_named(cell, capsys, tmp_path, off, which, sign):
    given_mm = {"stylus_radius_mm": 1.5, "tool_radius_mm": 4.0}[which] + sign * off
    if given_mm <= 0.05:
        given_mm = given_mm + 2 * off
    part = _edit(cell / "probe.csv", tmp_path / f"probe_{which}.csv", header=_swap(which, f"{given_mm:.4f}"))
    code, said = _diagnose(capsys, cell, part)
    assert code != 0 and "missing_effect" not in said, said


def test_a_cmm_part_with_a_wrong_radius_names_no_effect_and_the_radius(cell, capsys, tmp_path):
    """The CMM's points of the same wall placed by --best-fit (the robot's geometric errors move its frame),
    with the tool radius 0.5 mm too large."""
    part = _edit(cell / "part.csv", tmp_path / "part.csv", header=_swap("tool_radius_mm", 4.5))
    try:
        code = main(["part", "diagnose", str(START), str(cell / "cut.csv"), str(part), "--best-fit", "--json"])
    except SystemExit as e:
        code = e.code
    out, err = capsys.readouterr()
    assert code != 0 and "missing_effect" not in out, out
    assert "tool_radius_mm" in err, err


def test_a_cmm_part_far_off_along_the_tool_axis_is_refused_naming_its_height(cell, capsys, tmp_path):
    """Every z + 250 mm (metres for millimetres in a frame, or another datum): once learned, and cut 1.20 x
    exact; the wall a tool cut lies within `WALL_HEIGHT_MM` of its centre's path along its axis."""
    lines = (cell / "part.csv").read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("point,"))
    rows = [line.split(",") for line in lines[k + 1:]]
    part = tmp_path / "part.csv"
    part.write_text("\n".join(lines[:k + 1] + [",".join([*r[:3], f"{float(r[3]) + 250:.4f}"]) for r in rows]) + "\n")
    code = main(["part", "learn", str(START), str(cell / "cut.csv"), str(part), "--best-fit", "-o",
                 str(tmp_path / "learned.yaml")])
    err = capsys.readouterr().err
    assert code == 2 and not (tmp_path / "learned.yaml").exists()
    assert "part.csv: the points lie" in err and "mm along the tool axis" in err, err


def test_three_adjacent_touches_are_read_as_millimetres_with_a_coverage_warning(cell, capsys, tmp_path):
    """Three touches a few degrees apart span little in any unit: once taken for a part in inches ("20.9 x
    smaller ... multiply them by 25.4"); they lie on the wall as placed, so the unit is not in question."""
    lines = (cell / "probe.csv").read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("touch,"))
    (tmp_path / "three.csv").write_text("\n".join(lines[:k + 4]) + "\n")
    assert main(["part", "compare", str(START), str(cell / "cut.csv"), str(tmp_path / "three.csv")]) == 0
    out = capsys.readouterr().out
    assert "inches" not in out and "three.csv: warning: its 3 points span" in out, out


@pytest.mark.parametrize("kept", [0.6, 0.9])
def test_a_trace_cut_short_is_named_as_ending_before_the_probed_contour(cell, tmp_path, kept):
    """Once blamed on the approach of the touches by its end ("the approach ... makes 15 deg") or on the log
    ("they do not belong together")."""
    from stiffness.data.probe_log import read_probe
    from stiffness.data.trace_file import read_trace
    from stiffness.errors import DataError
    from stiffness.model.stiffness_model import StiffnessModel
    from stiffness.part.probe import read_probe_against

    lines = (cell / "cut.csv").read_text().splitlines()
    (tmp_path / "short.csv").write_text("\n".join(lines[:int(kept * len(lines))]) + "\n")
    with pytest.raises(DataError) as e:
        read_probe_against(read_probe(cell / "probe.csv"), read_trace(tmp_path / "short.csv"),
                           StiffnessModel.from_yaml(START).robot)
    text = str(e.value)
    assert "touches lie beyond where the trace" in text and "short.csv ends" in text, text
    assert "approach" not in text and "belong together" not in text, text

