"""A part read against the trace of its cut (`stiffness.part.rows`): the deviations it recovers, and every
bad input named by file and line (issue 29, item 2)."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stiffness.data.part_points import read_part, write_part
from stiffness.data.trace_file import COLUMNS, TraceFile, read_trace
from stiffness.errors import DataError
from stiffness.kinematics.robot import PoseConfig
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.part.compare import compare_part
from stiffness.part.rows import read_against
from stiffness.part.timing import when_made
from testlib.common import ROOT
from testlib.part import synthetic_cut
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"


@pytest.fixture(scope="module")
def truth() -> StiffnessModel:
    return StiffnessModel.from_yaml(TRUTH)


@pytest.fixture(scope="module")
def cut(truth, tmp_path_factory):
    return synthetic_cut(truth, tmp_path_factory.mktemp("cut"))


def test_the_deviation_along_the_normal_is_the_arms_deflection_there(cut, truth):
    """Recovery: each point's normal deviation is n . dX of the truth where the tool made it (the probe's
    2 um noise and the second-order geometry of the circle apart), and the normals lie across the tool;
    placed when the deflected tool made it, a point's row measures the truth's prediction there."""
    rows = read_against(read_part(cut.part), read_trace(cut.trace), truth.robot, smooth_hz=0)
    assert rows.used.all() and not rows.notes
    made = when_made(rows, truth)
    data = made.dataset(truth.robot, history_step_s=None)
    predicted = truth.predict(truth.context(data))[:, 0]
    np.testing.assert_allclose(data.deflection[:, 0], predicted, atol=0.0075)     # 2 um x 3 + 1.5 um geometry
    assert np.sqrt(np.mean((data.deflection[:, 0] - predicted) ** 2)) < 0.003
    assert np.abs(np.einsum("na,na->n", rows.normal, rows.axis)).max() < 1e-9
    assert np.all(np.diff(rows.u) > 0)               # the points in the order the tool made them
    # uncompensated: the nominal contour is the commanded one, so the part error is the deviation
    np.testing.assert_allclose(rows.nominal_mm, rows.deviation_mm, atol=1e-5)       # chords between cycles


@settings(max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(turn=st.floats(-180.0, 180.0), shift=st.tuples(st.floats(-50, 50), st.floats(-50, 50), st.floats(-20, 20)))
def test_the_part_frame_chosen_changes_nothing(cut, truth, tmp_path, turn, shift):
    """Invariance: the same points written in another part frame (turned about the tool axis and shifted)
    give the same deviations."""
    part = read_part(cut.part)
    rows = read_against(part, read_trace(cut.trace), truth.robot)
    frame = PoseConfig(xyz_mm=list(np.add(cut.frame.xyz_mm, shift)), rpy_deg=[0.0, 0.0, turn])
    T = frame.matrix()
    path = write_part(tmp_path / "moved.csv", (cut.points_base - T[:3, 3]) @ T[:3, :3] * 1000.0, 4.0, frame)
    again = read_against(read_part(path), read_trace(cut.trace), truth.robot)
    np.testing.assert_allclose(again.deviation_mm, rows.deviation_mm, atol=5e-4)       # the file holds 0.1 um


@given(xyz=st.tuples(*[st.floats(-2000.0, 2000.0)] * 3), rpy=st.tuples(*[st.floats(-180.0, 180.0)] * 3))
def test_a_frame_written_in_a_header_reads_back_to_the_points_precision(tmp_path_factory, xyz, rpy):
    """The frame in a part file's header places a point 1 m from its origin within 0.01 um (a tenth of the
    points' own precision) of where the frame written places it: the angles are not rounded to six digits."""
    frame = PoseConfig(xyz_mm=list(xyz), rpy_deg=list(rpy))
    path = write_part(tmp_path_factory.mktemp("frame") / "part.csv", np.array([[1000.0, 0.0, 0.0], [0.0, 1000.0, 0.0],
                                                                              [0.0, 0.0, 1000.0]]), 4.0, frame)
    back, T = read_part(path).frame, frame.matrix()
    np.testing.assert_allclose(back[:3, :3] * 1000.0, T[:3, :3] * 1000.0, rtol=0, atol=1e-5)     # 0.01 um
    np.testing.assert_allclose(back[:3, 3] * 1000.0, xyz, rtol=0, atol=5.1e-5)
    # a probe log's stylus frame, written the same way
    from stiffness.data.probe_log import read_probe, write_probe

    path = write_probe(path.with_name("probe.csv"), np.zeros((3, 6)), np.tile([1.0, 0.0, 0.0], (3, 1)), 4.0, 1.5, frame)
    np.testing.assert_allclose(read_probe(path).probe_frame.matrix()[:3, :3] * 1000.0, T[:3, :3] * 1000.0, rtol=0,
                               atol=1e-5)


def test_best_fit_hides_a_constant_offset_and_says_so(cut, truth, tmp_path):
    """Without a datum (the part's axes the base's, its origin 0.36 mm off): after the best fit its deviations are
    the datum's up to a rigid shift of the contour, which along a circle's normal is a first harmonic
    (a cos phi + b sin phi), and nothing more; the notes say what the fit hides."""
    part = read_part(cut.part)
    origin = np.array(cut.frame.xyz_mm) / 1000.0 + [0.0003, -0.0002, 0.0]
    moved = write_part(tmp_path / "nodatum.csv", (cut.points_base - origin) * 1000.0, 4.0, None)
    rows = read_against(read_part(moved), read_trace(cut.trace), truth.robot, best_fit=True)
    ref = read_against(part, read_trace(cut.trace), truth.robot)
    both = rows.used & ref.used
    assert both.sum() > 0.9 * len(part)
    d = _per_point(rows)[both] - _per_point(ref)[both]
    phi = np.arctan2(part.points_mm[both, 1], part.points_mm[both, 0])
    shift = np.column_stack([np.cos(phi), np.sin(phi)])
    left = d - shift @ np.linalg.lstsq(shift, d, rcond=None)[0]
    assert np.abs(left).max() < 0.004 and any("constant offset" in n for n in rows.notes)
    with pytest.raises(DataError, match="no part_frame.*--best-fit"):
        read_against(read_part(moved), read_trace(cut.trace), truth.robot)


def _per_point(rows) -> np.ndarray:
    out = np.full(len(rows.used), np.nan)
    out[rows.used] = rows.deviation_mm
    return out


@pytest.mark.parametrize("factor, unit", [(1 / 25.4, "inches"), (1 / 1000.0, "metres")])
def test_a_part_in_inches_or_metres_is_named_so(cut, truth, tmp_path, factor, unit):
    part = read_part(cut.part)
    path = write_part(tmp_path / f"{unit}.csv", part.points_mm * factor, 4.0, cut.frame)
    with pytest.raises(DataError, match=f"{path}: .*look like they are in {unit}"):
        read_against(read_part(path), read_trace(cut.trace), truth.robot)


def test_points_nowhere_near_the_path_are_named_by_line(cut, truth, tmp_path):
    part = read_part(cut.part)
    pts = part.points_mm.copy()
    radial = pts[:, :2] / np.linalg.norm(pts[:, :2], axis=1)[:, None]     # the part frame is at the centre
    pts[[10, 40], :2] += 6.0 * radial[[10, 40]]
    path = write_part(tmp_path / "far.csv", pts, 4.0, cut.frame)
    with pytest.raises(DataError) as e:
        read_against(read_part(path), read_trace(cut.trace), truth.robot)
    text = str(e.value)
    assert "2 point(s) are not on the contour" in text
    for k in (10, 40):
        assert f"{path}: line {part.lines[k]}: the point lies" in text


def test_a_trace_that_never_passes_the_part_is_refused(cut, truth, tmp_path):
    part = read_part(cut.part)
    elsewhere = PoseConfig(xyz_mm=list(np.add(cut.frame.xyz_mm, [250.0, 0.0, 0.0])), rpy_deg=cut.frame.rpy_deg)
    path = write_part(tmp_path / "elsewhere.csv", part.points_mm, 4.0, elsewhere)
    with pytest.raises(DataError, match="never passes the measured contour"):
        read_against(read_part(path), read_trace(cut.trace), truth.robot)


def test_points_the_tool_passed_twice_are_left_out_and_counted(truth, tmp_path):
    """With no mask, the points at the closed circle's start were cut at the entry and again at the exit."""
    c = synthetic_cut(truth, tmp_path, "overlap", mask_deg=0.0, points=360)
    rows = read_against(read_part(c.part), read_trace(c.trace), truth.robot)
    left = int((~rows.used).sum())
    assert 0 < left < 40
    assert any(f"{left} point(s) left out: the tool passed them twice" in n for n in rows.notes)


@pytest.mark.parametrize("text, match", [
    ("point,x_mm,y_mm,z_mm\n1,1,2,3\n", "tool_radius_mm: R' is missing"),
    ("# tool_radius_mm: 4\n# part_frame: {xyz_mm: [1, 2]\npoint,x_mm,y_mm,z_mm\n1,1,2,3\n", r"line 2.*not valid YAML"),
    ("# tool_radius_mm: 4\npoint,x_in,y_in,z_in\n1,1,2,3\n", r"line 2: missing column.*x_in is not millimetres"),
    ("# tool_radius_mm: 4\npoint,x_mm,y_mm,z_mm\n1,1,2,3\n2,1,two,3\n3,1,2,3\n4,1,2,3\n", r"line 4: x_mm, y_mm and z_mm must be numbers"),
    ("# tool_radius_mm: -4\npoint,x_mm,y_mm,z_mm\n1,1,2,3\n", "tool_radius_mm"),
    ("# tool_radius_mm: 4\n# colour: red\npoint,x_mm,y_mm,z_mm\n1,1,2,3\n", "colour"),
    ("# tool_radius_mm: 4\npoint;x_mm;y_mm;z_mm\n1;1,5;2;3\n", r"line 2: the fields are separated by ';'"),
    ("# tool_radius_mm: 4\npoint,x_mm,y_mm,z_mm\n1,1,2,3\n2,2,2,3\n1,1,2,3\n",
     r"line 5: point 1 is given twice \(line 3 and line 5\)"),
    ("# tool_radius_mm: 4\npoint,x_mm,y_mm,z_mm\n1,1,5,2,0,3,0\n2,1,5,2,5,-3,0\n",
     r"line 3: every row has more fields than the header's 4: decimal commas\?"),
    ("# tool_radius_mm: 4\n# tool radius mm: 5\npoint,x_mm,y_mm,z_mm\n1,1,2,3\n",
     r"line 2: tool_radius_mm is given twice \(line 1 and line 2\)"),
])
def test_a_bad_part_file_is_refused_naming_the_file_and_line(tmp_path, text, match):
    path = tmp_path / "bad.csv"
    path.write_text(text)
    with pytest.raises(DataError, match=match) as e:
        read_part(path)
    assert str(path) in str(e.value)


def test_rows_the_trace_lost_are_named_and_the_points_made_then_left_out(cut, truth, tmp_path, capsys):
    """150 rows removed from the middle of the trace (a gap in its cycle count): the gap is named by its cycles,
    its time and its size; the points made while it lasted (and a margin of path either side) are left out and
    named by line; every other point reads as it did from the whole trace, and so do the model's figures."""
    trace = read_trace(cut.trace)
    k = len(trace) // 2
    gapped = tmp_path / "gap.csv"
    with TraceFile(gapped) as f:
        f.write(np.delete(trace.table, np.s_[k:k + 150], axis=0))
    part = read_part(cut.part)
    clean = read_against(part, trace, truth.robot)
    rows = read_against(part, read_trace(gapped), truth.robot)
    lost_from, lost_to = trace.cycle[k], trace.cycle[k + 149]
    assert [(g.after_cycle + 1, g.after_cycle + g.lost) for g in rows.gaps] == [(lost_from, lost_to)]
    assert any(f"150 row(s) lost: cycles {lost_from} to {lost_to} (between t = {trace.time_s[k - 1]:.3f} and "
               f"{trace.time_s[k + 150]:.3f} s)" in n for n in rows.notes), rows.notes
    # the points the tool passed during the lost rows are left out, and only a margin of path more
    made_then = (clean.u > k - 1) & (clean.u < k + 150)
    left = ~rows.used
    assert left[clean.used][made_then].all() and 0 < made_then.sum() < left.sum() <= made_then.sum() + 8
    assert [x.line for x in rows.left_out] == part.lines[left].tolist()
    assert {x.why for x in rows.left_out} == {"trace_gap"}
    assert any(f"{left.sum()} point(s) left out: the trace lost the rows" in n and str(cut.part) in n
               for n in rows.notes)
    np.testing.assert_allclose(rows.deviation_mm, clean.deviation_mm[rows.used[clean.used]], atol=1e-6)
    # the model's account from the gapped trace is the whole trace's over the same points
    whole, gap = compare_part(truth, clean), compare_part(truth, rows)
    same = rows.used[clean.used]
    np.testing.assert_allclose(gap.model_mm, whole.model_mm[same], atol=0.001)  # 1 um: smoothed per side
    assert gap.summary()["model_missed_rms_mm"] == pytest.approx(whole.summary()["model_missed_rms_mm"], abs=5e-4)
    # and the command says so in its JSON
    assert main(["part", "compare", str(TRUTH), str(gapped), str(cut.part), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["left_out_count"] == left.sum() and [x["line"] for x in out["left_out"]] == part.lines[left].tolist()
    assert out["trace_gaps"] == [{"kind": "rows_lost", "after_cycle": int(lost_from) - 1, "lost_rows": 150,
                                  "from_s": trace.time_s[k - 1], "to_s": trace.time_s[k + 150]}]
    assert out["part_error_max_mm"] == pytest.approx(compare_part(truth, clean).summary()["part_error_max_mm"],
                                                     abs=0.005)


def test_a_cycle_count_that_does_not_rise_is_refused_by_line(cut, tmp_path):
    """Two runs in one file: the count starts again."""
    trace = read_trace(cut.trace)
    table = trace.table.copy()
    table[100:, 2] -= 50
    path = tmp_path / "twice.csv"
    with TraceFile(path) as f:
        f.write(table)
    with pytest.raises(DataError, match=f"{path}: line 102: the cycle count does not rise"):
        read_trace(path)


def test_joints_that_stood_still_then_jumped_are_named_and_the_points_passed_meanwhile_left_out(cut, truth, tmp_path):
    """A stalled PLC: the joints the trace holds stand still for 80 rows (the wrench goes on), then jump 8 mm to
    where the tool is. The trace holds every cycle but did not see the tool pass the points in between: they are
    left out and named with the jump; every other point reads as from the whole trace."""
    trace = read_trace(cut.trace)
    k = len(trace) // 2
    table = trace.table.copy()
    q = [COLUMNS.index(c) for c in COLUMNS if c.startswith("q")]
    table[k:k + 80, q] = table[k - 1, q]
    stalled = tmp_path / "stalled.csv"
    with TraceFile(stalled) as f:
        f.write(table)
    part = read_part(cut.part)
    clean = read_against(part, trace, truth.robot)
    rows = read_against(part, read_trace(stalled), truth.robot)
    assert len(rows.gaps) == 1 and rows.gaps[0].to_dict()["kind"] == "joints_jumped"
    jump = rows.gaps[0].to_dict()
    assert jump["after_cycle"] == trace.cycle[k + 79] and jump["still_rows"] == 80
    assert jump["moved_mm"] == pytest.approx(1000 * np.linalg.norm(clean.trace_tool[k + 80] - clean.trace_tool[k - 1]),
                                             rel=1e-4)
    assert any(f"the joints jumped between cycles {trace.cycle[k + 79]} and {trace.cycle[k + 80]}" in n
               and "after standing still for 80 cycle(s)" in n for n in rows.notes), rows.notes
    passed_then = (clean.u > k - 1) & (clean.u < k + 80)
    left = ~rows.used
    assert left[clean.used][passed_then].all() and 0 < passed_then.sum() < left.sum() <= passed_then.sum() + 8
    assert {x.why for x in rows.left_out} == {"trace_jump"}
    np.testing.assert_allclose(rows.deviation_mm, clean.deviation_mm[rows.used[clean.used]], atol=1e-6)
    whole, stall = compare_part(truth, clean), compare_part(truth, rows)
    np.testing.assert_allclose(stall.model_mm, whole.model_mm[rows.used[clean.used]], atol=0.001)


def test_a_trace_without_a_stall_names_no_jump(cut, truth):
    """The synthetic cut starts at rest at the contour and moves every row: nothing to name."""
    rows = read_against(read_part(cut.part), read_trace(cut.trace), truth.robot)
    assert rows.gaps == [] and rows.left_out == [] and rows.notes == []


@given(angles=st.lists(st.floats(-720, 720, allow_nan=False), min_size=2, max_size=50), turn=st.floats(-360, 360))
def test_the_span_of_angles_is_invariant_under_a_turn_and_bounded_by_a_full_turn(angles, turn):
    from stiffness.part.coverage import span_deg

    a = np.array(angles)
    assert 0.0 <= span_deg(a) <= 360.0
    assert span_deg(a + turn) == pytest.approx(span_deg(a), abs=1e-6)


def test_a_part_measured_on_a_narrow_arc_is_warned_of_and_one_all_round_is_not(cut, truth):
    from stiffness.part.coverage import note

    rows = read_against(read_part(cut.part), read_trace(cut.trace), truth.robot)
    assert note(rows) is None
    part = read_part(cut.part)
    keep = slice(0, len(part) // 12)                           # a twelfth of the points in the tool's order
    narrow = replace(part, points_mm=part.points_mm[keep], labels=part.labels[keep], lines=part.lines[keep])
    warned = note(read_against(narrow, read_trace(cut.trace), truth.robot))
    assert warned is not None and "warning" in warned and "deg of the" in warned, warned
