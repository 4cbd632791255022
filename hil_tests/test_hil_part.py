"""Learn from the part in the HIL (issue 29, "Done when"): cut, measure, learn, cut again; two parts teach a
third place; a hidden hysteresis is named from one part and nothing from the control.

The cuts run in lock step (`hil.lockstep`: the service, the virtual sensor and PLC stepped together as fast as
the host runs them), so the figures do not depend on how busy the host is; `benchmarks/bench_part.py`
measures the same in real time. The truth is examples/truth_reference.yaml and the scenario the paper's circle
(config/hil/circle.yaml) with its default robot stub.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from hil.circle import cut
from hil.scenario import load_scenario
from hil.testing import ROTATIONAL, scaled_model_file
from stiffness.data.part_points import read_part
from stiffness.data.trace_file import COLUMNS, read_trace
from stiffness.model.prior import Prior
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.part.diagnose import diagnose_parts
from stiffness.part.learn import learn
from stiffness.part.rows import read_against
from testlib.hil import ROOT
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"
A = [0.0, -60.0, 90.0, 0.0, 60.0, 0.0]          # the scenario's circle
B = [25.0, -45.0, 75.0, 0.0, 60.0, 30.0]        # a second place, tool down
C = [-20.0, -70.0, 100.0, 0.0, 60.0, -20.0]     # the third, elsewhere


def scenario_at(center):
    sc = load_scenario()
    sc.circle.center_q_deg = list(center)
    return sc


@pytest.fixture(scope="module")
def loop(tmp_path_factory):
    """Cut A and B with the too-stiff model (traced and measured); learn from A, and from A and B."""
    w = tmp_path_factory.mktemp("learn")
    start = scaled_model_file(TRUTH, 0.6, w / "start.yaml", keys=ROTATIONAL)     # 40 % too stiff
    model = StiffnessModel.from_yaml(start)
    prior = Prior.catalogue(model, 0.5)
    rows = {}
    cuts = {}
    for name, place in (("A", A), ("B", B)):
        cuts[name] = cut(scenario_at(place), TRUTH, start, w / name, w / f"{name}.csv", w / f"{name}_part.csv")
        rows[name] = read_against(read_part(w / f"{name}_part.csv"), read_trace(w / f"{name}.csv"), model.robot,
                                  f"part {name}")
    one = learn(model, [rows["A"]], prior)
    two = learn(model, [rows["A"], rows["B"]], prior)
    one.model.to_yaml(w / "learned_A.yaml")
    two.model.to_yaml(w / "learned_AB.yaml")
    return w, start, cuts, one, two


def test_one_part_teaches_the_model_to_cut_it_as_well_as_the_exact_model(loop):
    """A second cut of A with the model learned from the first is within 1.2 x the exact model's error."""
    w, _, cuts, one, _ = loop
    learned = cut(scenario_at(A), TRUTH, w / "learned_A.yaml", w / "A2")
    exact = cut(scenario_at(A), TRUTH, TRUTH, w / "A_exact")
    assert learned.mean_error_mm <= 1.2 * exact.mean_error_mm, (learned.mean_error_mm, exact.mean_error_mm)
    assert cuts["A"].mean_error_mm > 10 * exact.mean_error_mm          # the start was far off
    assert one.after_mm < 0.2 * one.before_mm
    # the part error read from the trace (its nominal contour: the joints less the correction) is the CMM's
    part_a = one.parts[0]
    assert np.mean(np.abs(part_a.nominal_mm)) == pytest.approx(cuts["A"].part.part_error_mm, rel=0.02)


def test_two_parts_teach_a_third_place_and_it_is_never_worse_than_the_start(loop):
    w, start, _, _, two = loop
    at_c = {name: cut(scenario_at(C), TRUTH, path, w / f"C_{name}").mean_error_mm
            for name, path in (("learned", w / "learned_AB.yaml"), ("exact", TRUTH), ("start", start))}
    assert at_c["learned"] <= 1.5 * at_c["exact"] and at_c["learned"] < at_c["start"], at_c
    assert len(two.determined) > 3            # two places see more than one


@pytest.mark.parametrize("hidden", [True, False], ids=["hysteresis-j1", "control"])
def test_the_part_names_a_hidden_hysteresis_at_joint_1_and_the_control_nothing(tmp_path, hidden):
    truth = StiffnessModel.from_yaml(TRUTH)
    if hidden:
        d = truth.to_dict()
        d["effects"].append({"effect": "hysteresis", "joint": 1, "offset_deg": 0.012})
        truth = StiffnessModel.from_dict(d, "truth + hysteresis@joint1", robot=truth.robot)
    truth_path = tmp_path / "truth.yaml"
    truth.to_yaml(truth_path)
    cut(load_scenario(), truth_path, TRUTH, tmp_path / "cut", tmp_path / "t.csv", tmp_path / "p.csv")
    model = StiffnessModel.from_yaml(TRUTH)
    rows = read_against(read_part(tmp_path / "p.csv"), read_trace(tmp_path / "t.csv"), model.robot)
    found = diagnose_parts(model, [rows], Prior.catalogue(model, 0.5))
    best = found.diagnosis.best
    if hidden:
        assert best is not None and (best.name, best.joint) == ("hysteresis", 1), found.message
        assert "where its loading state switches after each reversal of joint 1's torque" in found.message
    else:
        assert best is None and found.diagnosis.verdict == "no_missing_effect", found.message


def test_a_trace_that_lost_rows_reads_as_the_whole_one_and_names_the_gap(loop, tmp_path, capsys):
    """The service's trace of cut A with 150 rows removed from its middle (a gap in its cycle count, as a stalled
    writer leaves): `part compare` and `part learn` name the gap and the points made during it, leave those out,
    and their figures are the whole trace's."""
    w, start, _, _, _ = loop
    lines = (w / "A.csv").read_text().splitlines(keepends=True)
    k = len(lines) // 2
    gapped = tmp_path / "A_gap.csv"
    gapped.write_text("".join(lines[:k] + lines[k + 150:]))
    lost_from = int(lines[k].split(",")[COLUMNS.index("cycle")])
    got = {}
    for name, trace in (("whole", w / "A.csv"), ("gap", gapped)):
        assert main(["part", "compare", str(start), str(trace), str(w / "A_part.csv"), "--json"]) == 0
        got[name] = json.loads(capsys.readouterr().out)
        assert main(["part", "learn", str(start), str(trace), str(w / "A_part.csv"), "-o",
                     str(tmp_path / f"{name}.yaml"), "--json"]) == 0
        got[name]["learn"] = json.loads(capsys.readouterr().out)
    whole, gap = got["whole"], got["gap"]
    assert whole["left_out_count"] == 0 and whole["trace_gaps"] == []
    assert [(g["after_cycle"] + 1, g["lost_rows"]) for g in gap["trace_gaps"]] == [(lost_from, 150)]
    assert 0 < gap["left_out_count"] < 40 and {x["why"] for x in gap["left_out"]} == {"trace_gap"}
    assert gap["points"] + gap["left_out_count"] == whole["points"]
    for key in ("part_error_max_mm", "part_error_mean_mm", "model_missed_rms_mm", "model_missed_max_mm"):
        assert gap[key] == pytest.approx(whole[key], abs=0.005), key
    assert gap["learn"]["rms_after_mm"] == pytest.approx(whole["learn"]["rms_after_mm"], abs=0.003)
    assert any(f"150 row(s) lost: cycles {lost_from} to {lost_from + 149}" in n for n in gap["learn"]["notes"])
