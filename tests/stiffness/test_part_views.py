"""What `part diagnose|learn|compare` show, held to what they compute (issue 35, item 15): the marks of a hidden
hysteresis where its step is, the report's columns and colours, the worst component in the part's own axes,
the learn report's figures from the same numbers as its text, the covariance's count of rows, and no numpy
warning on the way."""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest
from matplotlib.colors import to_hex

from stiffness.data.part_points import read_part
from stiffness.data.trace_file import read_trace
from stiffness.diagnose.report import to_dict
from stiffness.fit.gross_errors import repeat_deviation
from stiffness.model.prior import Prior
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.part.compare import at_points, compare_part
from stiffness.part.diagnose import diagnose_parts
from stiffness.part.learn import learn
from stiffness.part.report import diagnose_report, learn_figure, load_figure
from stiffness.part.rows import read_against
from testlib.common import ROOT
from testlib.part import synthetic_cut
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"


@pytest.fixture(scope="module")
def hidden(tmp_path_factory):
    """A part cut by the truth with a hysteresis at joint 1 (0.012 deg), diagnosed with the truth's springs."""
    truth = StiffnessModel.from_yaml(TRUTH)
    d = truth.to_dict()
    d["effects"].append({"effect": "hysteresis", "joint": 1, "offset_deg": 0.012})
    with_h = StiffnessModel.from_dict(d, "truth with hysteresis at joint 1", robot=truth.robot)
    cut = synthetic_cut(with_h, tmp_path_factory.mktemp("hidden"), "H")
    rows = read_against(read_part(cut.part), read_trace(cut.trace), truth.robot)
    return diagnose_parts(truth, [rows], Prior.catalogue(truth, 0.5))


def _share_along_contour(pd):
    """The named effect's fitted share at the first part's points, in time order, and their angles."""
    rows = pd.parts[0]
    first = pd.data.config == rows.label
    share = at_points(rows, pd.data.subset(np.nonzero(first)[0]), pd.diagnosis.best.contribution[first][:, 0])
    o = np.argsort(rows.t, kind="stable")
    return share[o], rows.arc_deg[o]


def _mid_steps(share: np.ndarray, arc: np.ndarray, steps: int = 2, plateau_deg: float = 12.0) -> list[float]:
    """Where the share crosses halfway between its levels either side of each of its largest jumps (deg):
    the middle of each step as the eye finds it, computed from the share alone."""
    jumps = np.argsort(np.abs(np.diff(share)))[::-1]
    out: list[float] = []
    for k in jumps:
        if len(out) == steps:
            break
        if any(abs((arc[k] - m + 180) % 360 - 180) < 3 * plateau_deg for m in out):
            continue                        # a neighbour of a step already found
        side = np.sign(arc[k + 1] - arc[k])          # the direction the angle runs in time
        level = [share[np.abs(arc - (arc[k] + s * plateau_deg)) < 2.0].mean() for s in (-side, side)]
        near = np.nonzero(np.abs(arc - arc[k]) < plateau_deg)[0]
        x = share[near] - 0.5 * sum(level)
        i = np.nonzero(x[1:] * x[:-1] < 0)[0]
        out += [float(arc[near][j] + (arc[near][j + 1] - arc[near][j]) * x[j] / (x[j] - x[j + 1])) for j in i[:1]]
    return out


def test_the_marks_are_where_the_fitted_share_steps_not_where_the_torque_turns(hidden):
    best = hidden.diagnosis.best
    assert (best.name, best.joint) == ("hysteresis", 1), hidden.message
    steps = sorted(m % 360 for m in _mid_steps(*_share_along_contour(hidden)))
    marks = sorted(m % 360 for m in hidden.marks_deg)
    assert len(marks) == 2 and len(steps) == 2, (marks, steps)
    assert np.allclose(marks, steps, atol=2.0), (marks, steps)
    # the text names both: the step at the marks, and the torque's turns it follows (a breakaway later)
    turns = [float(v) for v in re.search(r"the torque turns at ([\d.]+), ([\d.]+) deg", hidden.message).groups()]
    assert all(abs(t - m) > 8.0 for t, m in zip(sorted(turns), marks)), (turns, marks)
    assert f"a step at {marks[0]:.0f}, {marks[1]:.0f} deg along the contour" in hidden.message


def test_the_worst_component_of_a_part_is_its_normal(hidden):
    worst = to_dict(hidden.diagnosis)["worst"]
    assert worst["component"] == "normal"
    assert "dx" not in hidden.diagnosis.worst["scores"]["component"]


def test_the_report_names_where_each_candidate_sits(hidden, tmp_path):
    """link_bending sits on a link: the table's column says where, not 'joint'."""
    pd = hidden
    bend = next(c for c in pd.diagnosis.candidates if c.effect.location_key == "link")
    pd.diagnosis.candidates.remove(bend)
    pd.diagnosis.candidates.insert(0, bend)
    try:
        rep = diagnose_report(pd.message, "warn", compare_part(pd.diagnosis.fit.model, pd.parts[0]), pd, "cmd")
        rep.write(tmp_path)
    finally:
        pd.diagnosis.candidates.remove(bend)
        pd.diagnosis.candidates.append(bend)
    html = (tmp_path / "index.html").read_text()
    header = re.search(r"<tr>(\s*<th>effect</th>.*?)</tr>", html, re.DOTALL).group(1)
    assert re.findall(r"<th>([^<]*)</th>", header)[:2] == ["effect", "where"]
    row = re.search(r"<tr>\s*<td>link_bending</td>\s*<td>([^<]*)</td>", html)
    assert row and row.group(1) == f"link {bend.joint}"


def test_the_load_figure_gives_every_force_and_joint_a_colour_of_its_own(hidden):
    fig = load_figure(compare_part(hidden.diagnosis.fit.model, hidden.parts[0]))
    colours = [to_hex(line.get_color()) for ax in fig.axes for line in ax.get_lines() if line.get_label()[0] != "_"]
    assert len(colours) == 9 and len(set(colours)) == 9, colours


@pytest.fixture(scope="module")
def learned(tmp_path_factory):
    truth = StiffnessModel.from_yaml(TRUTH)
    start = truth.copy()
    start.theta = 0.6 * start.theta
    cut = synthetic_cut(truth, tmp_path_factory.mktemp("learn"), "A")
    rows = read_against(read_part(cut.part), read_trace(cut.trace), start.robot)
    return learn(start, [rows], Prior.catalogue(start, 0.5)), cut, start


def test_the_learn_figure_shows_the_figures_the_text_prints(learned):
    result = learned[0]
    text = "\n".join(result.lines())
    printed = re.search(r"RMS ([\d.]+) mm before, ([\d.]+) mm after", text).groups()
    legend = [re.search(r"RMS ([\d.]+) mm", line.get_label()).group(1)
              for line in learn_figure(result).axes[0].get_lines() if "RMS" in line.get_label()]
    assert legend == list(printed), (legend, printed)


def test_the_learned_covariance_counts_the_points_as_measured_rows(learned):
    result = learned[0]
    n = int(np.isfinite(result.fit.residual[:, 0]).sum())       # the points fitted
    source = result.model.covariance["source"]
    rows = len(result.fit.residual)
    assert n == sum(int(p.used.sum()) for p in result.parts) < rows
    assert f"({n} rows measured; {rows - n} more carry only the load's history)" in source, source


def test_no_part_command_warns_of_all_nan_slices(learned, tmp_path, capsys):
    """A fit that judges gross errors looks at the repeats of each row; a part's rows measure the normal alone
    and the trace's rows between them nothing, which numpy's nanmedian warned about on every such group."""
    _, cut, model = learned
    wrong = tmp_path / "radius5.csv"
    wrong.write_text(cut.part.read_text().replace("# tool_radius_mm: 4\n", "# tool_radius_mm: 5\n"))
    model.to_yaml(tmp_path / "start.yaml")
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message="All-NaN slice encountered")
        # compare reads it; diagnose refuses it as part learn does (a radius 1 mm off), naming no effect
        for action, code in (("compare", 0), ("diagnose", 2)):
            assert main(["part", action, str(tmp_path / "start.yaml"), str(cut.trace), str(wrong)]) == code, action
        learn(model, [read_against(read_part(wrong), read_trace(cut.trace), model.robot)], Prior.catalogue(model, 0.5))
    capsys.readouterr()


def test_repeats_that_measure_one_component_or_none_differ_without_warning():
    """The cause: the median of a group's other rows over components none of them measures. Each row now
    differs from the others' median where they measure, and has no repeat (NaN) where they do not."""
    resid = np.full((5, 6), np.nan)
    resid[:3, 0] = [1.0, 2.0, 4.0]           # three rows measure the first component; two rows measure nothing
    with warnings.catch_warnings():
        warnings.filterwarnings("error", message="All-NaN slice encountered")
        dev, factor = repeat_deviation(resid, np.zeros(5, dtype=int))
    assert dev[:3, 0].tolist() == [1.0 - 3.0, 2.0 - 2.5, 4.0 - 1.5]
    assert np.isnan(dev[:, 1:]).all() and np.isnan(dev[3:]).all()
    assert np.allclose(factor, 1.25)
