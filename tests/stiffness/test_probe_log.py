"""The robot probes its own part (issue 46): the probe log's format, its reading against the trace with the
robot's geometric errors cancelled, and its refusals, each naming the file and the touch's line."""

from __future__ import annotations

import re
from functools import lru_cache
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stiffness.data.part_points import read_part
from stiffness.data.probe_log import is_probe_log, read_probe, write_probe
from stiffness.data.trace_file import read_trace
from stiffness.errors import DataError
from stiffness.kinematics.robot import PoseConfig
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.part.contour import ToolPath
from stiffness.part.probe import read_probe_against
from stiffness.part.probe_geometry import touches_in_base
from stiffness.part.rows import read_against
from testlib.part import STYLUS_RADIUS_MM, TOOL_RADIUS_MM, probe_touches, synthetic_cut

ROOT = Path(__file__).resolve().parents[2]
NOMINAL = StiffnessModel.from_yaml(ROOT / "examples" / "truth_reference.yaml")        # the datasheet's DH table
BUILT = StiffnessModel.from_yaml(ROOT / "examples" / "truth_geometric_errors.yaml")   # 0.2 mm, 0.02 deg off it
TCP = PoseConfig(xyz_mm=[0.0, 0.0, 250.0])


@lru_cache(maxsize=1)
def _cut(folder: str):
    """A part cut by the robot as built (its geometric errors), and its own probe of it."""
    cut = synthetic_cut(BUILT, Path(folder), points=120, noise_um=0.0)
    q, n, pick = probe_touches(cut, BUILT.robot, touches=36)
    return cut, q, n, pick


@pytest.fixture(scope="module")
def probed(tmp_path_factory):
    return _cut(str(tmp_path_factory.mktemp("probe")))


def _log(folder: Path, q, n, name="probe.csv", **kw) -> Path:
    args = {"tool_radius_mm": TOOL_RADIUS_MM, "stylus_radius_mm": STYLUS_RADIUS_MM, "probe_frame": TCP}
    args.update(kw)
    return write_probe(folder / name, q, n, **args)


def test_geometric_errors_cancel_in_the_probe_and_not_in_the_cmm(probed, tmp_path):
    """Read through the datasheet's kinematics, the robot's own touches of a wall read as the CMM's points of it
    read through the kinematics as built: within 1 um, where the deviations span 0.4 mm. The CMM's points read
    through the datasheet's kinematics, with the part's true frame, are off by the robot's geometric error
    (some 1.3 mm), taken for deflection."""
    cut, q, n, pick = probed
    trace = read_trace(cut.trace)
    rows = read_probe_against(read_probe(_log(tmp_path, q, n)), trace, NOMINAL.robot)
    exact = read_against(read_part(cut.part), trace, BUILT.robot)
    assert rows.used.all() and exact.used.all()
    assert np.ptp(exact.deviation_mm[pick]) > 0.3
    assert np.abs(rows.deviation_mm - exact.deviation_mm[pick]).max() < 0.001
    cmm = read_against(read_part(cut.part), trace, NOMINAL.robot)
    assert np.abs(cmm.deviation_mm - exact.deviation_mm).max() > 0.5


@settings(max_examples=25, deadline=None)
@given(q=st.lists(st.lists(st.floats(-170, 170), min_size=6, max_size=6), min_size=3, max_size=8),
       d=st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(0.1, 1)), min_size=8, max_size=8),
       rs=st.floats(0.1, 10.0), r=st.floats(0.5, 20.0))
def test_a_written_log_reads_back(tmp_path_factory, q, d, rs, r):
    """Joints to 1e-6 deg, unit approach directions, the header's radii and frame: a round trip."""
    folder = tmp_path_factory.mktemp("rt")
    q = np.array(q)
    d = np.array(d[: len(q)])
    d /= np.linalg.norm(d, axis=1)[:, None]
    path = _log(folder, q, d, tool_radius_mm=r, stylus_radius_mm=rs, probing_speed_mm_s=5.0, trigger_latency_ms=1.0)
    assert is_probe_log(path)
    log = read_probe(path)
    assert np.abs(log.q_deg - q).max() <= 1e-6
    assert np.abs(log.approach - d).max() <= 2e-6
    assert log.stylus_radius_mm == pytest.approx(rs, rel=1e-5) and log.tool_radius_mm == pytest.approx(r, rel=1e-5)
    assert log.overtravel_mm == pytest.approx(0.005)


def test_a_cmm_part_is_not_a_probe_log(probed):
    assert not is_probe_log(probed[0].part)


def test_the_stated_overtravel_is_taken_back_along_the_approach(probed, tmp_path):
    """Joints latched v tau past the contact, with v and tau stated, read as the contact itself."""
    _, q, n, _ = probed
    log = read_probe(_log(tmp_path, q, n, probing_speed_mm_s=10.0, trigger_latency_ms=2.0))
    base = read_probe(_log(tmp_path, q, n, name="plain.csv"))
    moved = touches_in_base(log, NOMINAL.robot).points - touches_in_base(base, NOMINAL.robot).points
    assert np.allclose(moved, -0.02e-3 * log.approach, atol=1e-12)


def test_a_log_that_states_no_speed_and_latency_is_read_with_a_warning_naming_both(probed, tmp_path):
    cut, q, n, _ = probed
    plain = read_probe_against(read_probe(_log(tmp_path, q, n)), read_trace(cut.trace), NOMINAL.robot)
    stated = read_probe_against(read_probe(_log(tmp_path, q, n, name="stated.csv", probing_speed_mm_s=5.0,
                                                trigger_latency_ms=1.0)), read_trace(cut.trace), NOMINAL.robot)
    warned = [x for x in plain.notes if "warning" in x]
    assert len(warned) == 1 and "probing_speed_mm_s and trigger_latency_ms" in warned[0], plain.notes
    assert not [x for x in stated.notes if "warning" in x], stated.notes


def _refusal(probed, tmp_path, **change) -> str:
    cut, q, n, _ = probed
    q, n = q.copy(), n.copy()
    if "edit" in change:
        change.pop("edit")(q, n)
    path = _log(tmp_path, q, n, **change)
    with pytest.raises(DataError) as e:
        read_probe_against(read_probe(path), read_trace(cut.trace), NOMINAL.robot)
    return str(e.value)


def test_an_approach_away_from_the_wall_is_refused_by_line(probed, tmp_path):
    def reverse(q, n):
        n[4] = -n[4]                                   # the fifth touch moved away from the wall
        n[9] = np.cross([0.0, 0.0, 1.0], n[9])         # the tenth along it
    text = _refusal(probed, tmp_path, edit=reverse)
    assert re.search(r"line 10: the approach \(.*\) is not toward the contour: it makes 1(79|80) deg", text), text
    assert re.search(r"line 15: the approach \(.*\) is not toward the contour: it makes (89|90|91) deg", text), text
    assert "2 touch(es)" in text


def test_a_trigger_far_from_the_traced_path_is_refused_by_line(probed, tmp_path):
    def stray(q, n):
        q[6, 0] += 0.5                                 # 0.5 deg on A1: some 15 mm along the circle's outside
    text = _refusal(probed, tmp_path, edit=stray)
    assert "line 12: the trigger lies" in text and "off the wall the trace" in text and "far from any point" in text


def test_a_stylus_radius_that_does_not_fit_names_the_one_that_does(probed, tmp_path):
    text = _refusal(probed, tmp_path, stylus_radius_mm=STYLUS_RADIUS_MM + 5.0)
    assert "stylus_radius_mm = 6.5 does not fit" in text
    fit = float(text.split("a stylus radius of about ")[1].split(" mm")[0])
    assert abs(fit - STYLUS_RADIUS_MM) < 1.0           # within the arm's deflection of the true radius


def test_a_probe_of_another_contour_is_refused_as_not_belonging(probed, tmp_path):
    def elsewhere(q, n):
        q[:, 0] += 5.0                                 # every touch 5 deg on A1 away: the circle some 150 mm off
    text = _refusal(probed, tmp_path, edit=elsewhere)
    assert "never passes the probed contour" in text and "they do not belong together" in text


def test_a_part_frame_in_the_log_is_refused_as_meaningless(probed, tmp_path):
    _, q, n, _ = probed
    path = _log(tmp_path, q, n)
    text = path.read_text().replace("# probe_frame", "# part_frame: {xyz_mm: [1800, 0, 800]}\n# probe_frame")
    path.write_text(text)
    with pytest.raises(DataError, match=r"probe\.csv: part_frame: a probe log needs no part frame"):
        read_probe(path)


@pytest.mark.parametrize("header, message", [
    ("# stylus_radius_mm: 1.5", "stylus_radius_mm"),
    ("# probing_speed_mm_s: 5", "go together"),
])
def test_a_bad_header_is_named(probed, tmp_path, header, message):
    _, q, n, _ = probed
    path = _log(tmp_path, q, n)
    text = path.read_text()
    if "speed" in header:
        text = text.replace("# probe_frame", f"{header}\n# probe_frame")
    else:
        text = text.replace(header, "# stylus_radius_mm: -1")
    path.write_text(text)
    with pytest.raises(DataError, match=message):
        read_probe(path)


def test_a_key_given_twice_is_refused_at_its_second_line(probed, tmp_path):
    """PyYAML keeps the last of two keys in silence: a second stylus radius would pass for the first."""
    _, q, n, _ = probed
    path = _log(tmp_path, q, n)
    lines = path.read_text().splitlines()
    k = next(i for i, line in enumerate(lines) if line.startswith("# stylus_radius_mm"))
    lines.insert(k + 1, "# stylus_radius_mm: 2")
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(DataError, match=rf"probe\.csv: line {k + 2}: stylus_radius_mm is given twice \(line {k + 1}"):
        read_probe(path)


@pytest.mark.parametrize("edit, message", [
    (lambda text: text.replace("touch,q1_deg,", "touch,q1,"), r"line \d+: missing column\(s\) q1_deg; a probe log"),
    (lambda text: "\n".join(line if line.startswith("#") else line.replace(",", ";") for line in text.splitlines()),
     r"line \d+: the fields are separated by ';'"),
    (lambda text: "\n".join(line for line in text.splitlines() if line.startswith("#")), r"no header row.*touch,q1_deg"),
    (lambda text: text + "\n".join(line for line in text.splitlines() if line[:1].isdigit()) + "\n",
     r"line \d+: touch 1 is given twice \(line \d+ and line \d+\)"),
], ids=["misspelt-header", "semicolons", "header-only", "pasted-twice"])
def test_a_probe_log_with_a_broken_table_is_read_as_a_probe_log_and_refused_by_line(probed, tmp_path, edit, message):
    """Not taken for a CMM part (its '#' keys say it is a probe log), which named keys the user never wrote."""
    _, q, n, _ = probed
    path = _log(tmp_path, q, n)
    path.write_text(edit(path.read_text()))
    assert is_probe_log(path)
    with pytest.raises(DataError, match=message):
        read_probe(path)


def test_a_zero_approach_is_refused_by_line(probed, tmp_path):
    _, q, n, _ = probed
    n = n.copy()
    n[2] = 0.0
    with pytest.raises(DataError) as e:
        read_probe(_log(tmp_path, q, n))
    assert "line 8: the approach direction is zero" in "\n".join(e.value.problems)


@settings(max_examples=200, deadline=None)
@given(radius_mm=st.floats(5.0, 200.0), step_mm=st.floats(0.05, 0.5), offset_mm=st.floats(0.5, 4.0),
       late=st.lists(st.integers(0, 399), max_size=40), phi=st.floats(0.3, 5.9), inside=st.booleans())
def test_the_wall_normal_is_the_paths_across_reports_that_came_late(radius_mm, step_mm, offset_mm, late, phi, inside):
    """A circular path traced by reports ``step_mm`` apart, some missing (a robot's report the host took late,
    up to several in a row): the vector from the path to a point ``offset_mm`` off it is the circle's radial
    within half the angle the path turns along the longest chord beside it, and its distance the offset within
    that chord's sagitta; the nearest report alone tilts it by atan(s / D) (10 deg in a loaded run's failing
    RSI probe)."""
    u = np.arange(0.0, 2 * np.pi * radius_mm, step_mm) / radius_mm
    keep = np.ones(len(u), dtype=bool)
    keep[[k for k in late if k < len(u)]] = False
    keep[0] = keep[-1] = True
    u = u[keep]
    c2 = radius_mm * np.column_stack([np.cos(u), np.sin(u)]) / 1000.0
    radial = np.array([np.cos(phi), np.sin(phi)])
    x2 = (radius_mm + (-offset_mm if inside else offset_mm)) * radial[None, :] / 1000.0
    dist, n = ToolPath(np.column_stack([c2, np.zeros(len(c2))]), np.array([0.0, 0.0, 1.0])).across(x2)
    chord = float(np.diff(u).max())                   # the longest chord's angle
    tilt = np.degrees(np.arccos(np.clip(abs(n[0] @ radial), -1.0, 1.0)))
    assert tilt <= np.degrees(chord) / 2 + 1e-6, (tilt, np.degrees(chord))
    assert n[0] @ radial * (-1 if inside else 1) > 0                                  # toward the point
    sagitta_mm = radius_mm * (1 - np.cos(chord / 2))
    assert abs(dist[0] * 1000.0 - offset_mm) <= sagitta_mm + offset_mm * (1 - np.cos(chord / 2)) + 1e-9
