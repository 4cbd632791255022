"""The paper's circle and the part loop through the robot road (issues 37 and 43): a virtual KUKA RSI robot (4 ms)
or ABB EGM robot (path correction every 48 ms, as shipped) in the PLC's place, the service without a PLC.

`stiffcomp hil circle --robot-interface` with the too-stiff model: the summary names the road, its late answers
and the answers' round trip at the robot, and the end-to-end delay (EGM's 48 ms sample adds up to its length).
`part compare` reads the trace the road left and gives the HIL's part error within 10 %; the model learned from
it (more compliant, not less) cuts the next part through the same road within 1.2 x the exact model's error,
and the exact model takes >= 90 % of the path error away, as through the PLC. In real time: the robot road has
no lock step."""

from __future__ import annotations

import numpy as np
import pytest

from hil.circle import cut, run_circle
from hil.scenario import load_scenario
from hil.testing import ROTATIONAL, scaled_model_file
from stiffness.data.part_points import read_part
from stiffness.data.trace_file import read_trace
from stiffness.model.prior import Prior
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.part.learn import learn
from stiffness.part.rows import read_against
from testlib.hil import ROOT

TRUTH = ROOT / "examples" / "truth_reference.yaml"


@pytest.mark.parametrize("interface", ["kuka_rsi", "abb_egm"])
def test_the_circle_and_the_part_loop_through_the_robot_road(tmp_path, interface):
    start = scaled_model_file(TRUTH, 0.6, tmp_path / "start.yaml", keys=ROTATIONAL)       # 40 % too stiff
    model = StiffnessModel.from_yaml(start)
    sc = load_scenario()
    res = run_circle(sc, TRUTH, start, workdir=tmp_path / "A", trace=tmp_path / "A.csv", cmm=tmp_path / "A_part.csv",
                     robot_interface=interface)
    s = res.summary
    assert s["robot_interface"] == interface and s["mean_error_mm_uncompensated"] > 0.2, s
    # the answers' round trip is measured (its figures: benchmarks/bench_robot_road.py, docs/benchmarks.md; a
    # bound here would time the host: with both cores busy its 99th percentile read 8.4 ms once in two runs)
    assert s["cycles"] > 1000 and 0.0 < s["reply_latency_p99_ms"] < float("inf"), s
    # the virtual robot runs below the service, so a loaded host makes it late now and then; it never stopped
    log = res.passes["compensated"].log
    assert 0 <= s["late_answers"] < len(log.t) and np.isnan(log.stopped_at), s
    sample_ms = 48.0 if interface == "abb_egm" else 0.0
    assert s["delay_ms"] is not None and 0.0 < s["delay_ms"] < 30.0 + sample_ms, s
    low, high = s["delay_band_ms"]             # issue 45, item 5: the road's delay in its band, or the run says so
    assert low <= s["delay_ms"] <= high or (
        not s["timing"]["trustworthy"] and "end-to-end delay" in s["timing"]["verdict"]), s
    rows = read_against(read_part(tmp_path / "A_part.csv"), read_trace(tmp_path / "A.csv"), model.robot, "part A")
    compared = float(np.mean(np.abs(rows.nominal_mm)))
    assert compared == pytest.approx(s["part_error_mm"], rel=0.10), (compared, s["part_error_mm"])
    one = learn(model, [rows], Prior.catalogue(model, 0.5))
    assert one.after_mm < 0.3 * one.before_mm
    # a model already too stiff becomes more compliant, not less, and is written without a problem
    grown = [after / before for _, before, after in one.changes[:5] if before > 0]
    assert grown and min(grown) > 1.0 and one.problems == [], (one.changes[:5], one.problems)
    one.model.to_yaml(tmp_path / "learned.yaml")
    learned = cut(sc, TRUTH, tmp_path / "learned.yaml", tmp_path / "A2", lockstep=False, robot_interface=interface)
    exact = cut(sc, TRUTH, TRUTH, tmp_path / "A_exact", lockstep=False, robot_interface=interface)
    assert learned.mean_error_mm <= 1.2 * exact.mean_error_mm, (learned.mean_error_mm, exact.mean_error_mm)
    assert 1.0 - exact.mean_error_mm / s["mean_error_mm_uncompensated"] >= 0.90, (exact.mean_error_mm, s)
    assert s["mean_error_mm"] > 5 * exact.mean_error_mm
