"""The dynamic compensation in the HIL (issue 26, "Done when"), in lock step (`hil.lockstep`: the service's own
cycle, the virtual sensor's frames and the PLC's logic stepped together, deterministic).

On the paper's circle with the ringing robot stub (10 Hz and 16 Hz, 3 %): the modes identified from a tap test
(`hil.dynamics`, what `stiffcomp modes` does), the delay measured on the static pass of the same run:

* the peak path error in the entry and exit windows is at most 40 % of the static compensator's, 50 % with 8 ms
  of extra delay, and the steady mean no worse; the injected delay shows in the measured one;
* with the modes' frequency 20 % off (either way) the exact cancellation fails, so the robust filter
  (``added_damping`` 0.1) is what holds: its window peaks stay below the static compensator's and its steady
  mean no worse (docs/dynamics.md: 40 % is not reachable then; why);
* with hysteresis at joint 1 (0.012 deg), the exact model leaves at most 10 % of the uncompensated mean error,
  static and dynamic; the static compensator's largest error where joint 1's torque reverses is at most twice
  its largest elsewhere, the dynamic one's no larger than the static one's there (elsewhere the dynamic path
  takes the ringing away, so its own ratio is no measure), and springs alone leave more;
* docs/dynamics.md's rows at 8 ms of extra delay, the modes as identified without and with the feedforward
  (which lowers the entry peak and raises the exit's), are what this run gives.

`benchmarks/bench_dynamics.py` prints the same figures for every variant, in lock step or in real time.
"""

from __future__ import annotations

import re

import numpy as np
import pytest

from hil.circle import run_circle
from hil.dynamics import DynamicOptions, compare
from hil.lockstep import run_lockstep
from hil.report import evaluate_pass
from hil.scenario import load_scenario
from stiffness.model.stiffness_model import StiffnessModel
from testlib.hil import ROOT

TRUTH = ROOT / "examples" / "truth_reference.yaml"
ROBUST = 0.1
REVERSALS_DEG = ((40.0, 120.0), (200.0, 300.0))      # where joint 1's torque turns on this circle


def cell_scenario():
    """The shipped scenario with the PLC at the library's own 1 ms task, as a cell runs it: in lock step the host
    sets no floor on the PLC's cycle, and the program takes each answer a cycle after it asked (docs/hil.md), so
    the PLC's cycle is part of the delay these figures are about."""
    sc = load_scenario()
    sc.plc.period_ms = 1.0
    return sc


@pytest.fixture(scope="module")
def result():
    sc = cell_scenario()
    exact = DynamicOptions()
    off = [DynamicOptions(mode_error=e, added_damping=ROBUST) for e in (0.2, -0.2)]
    return compare(sc, StiffnessModel.from_yaml(TRUTH), sc.resolve(sc.model),
                   [(0.0, [exact, *off]), (8.0, [exact, DynamicOptions(feedforward=True)])])


@pytest.mark.parametrize("case, limit", [(0, 0.40), (1, 0.50)], ids=["0 ms", "8 ms extra"])
def test_entry_and_exit_peaks_fall_below_the_limit_and_the_steady_error_is_no_worse(result, case, limit):
    c = result["cases"][case]
    row = c["dynamic"][0]
    assert row["entry_ratio"] <= limit and row["exit_ratio"] <= limit, (row, c["static"])
    assert row["figures"]["steady_mean_mm"] <= c["static"]["steady_mean_mm"], (row, c["static"])


def test_the_injected_delay_shows_in_the_measured_one(result):
    zero, eight = (c["delay_ms"] for c in result["cases"])
    assert 4.0 < zero < 12.0 and eight - zero == pytest.approx(8.0, abs=0.1)


def doc_row(delay: str, variant: str) -> list[str]:
    """The cells of docs/dynamics.md's figures table in the block of extra ``delay`` whose model is ``variant``."""
    inside = False
    for line in (ROOT / "docs" / "dynamics.md").read_text().splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if line.startswith("|") and len(cells) == 6:
            inside = cells[0].startswith(delay) if cells[0] else inside
            if inside and cells[1] == variant:
                return cells
    raise AssertionError(f"docs/dynamics.md has no row {variant!r} at {delay}")


@pytest.mark.parametrize("k, variant", [(0, "as identified"), (1, "as identified, with the feedforward")],
                         ids=["without", "with the feedforward"])
def test_the_docs_rows_at_8_ms_are_what_the_run_gives(result, k, variant):
    row = result["cases"][1]["dynamic"][k]
    cells = doc_row("8 ms", variant)
    for cell, key, ratio in ((cells[3], "entry_peak_mm", "entry_ratio"), (cells[4], "exit_peak_mm", "exit_ratio")):
        mm, pct = re.fullmatch(r"([\d.]+) mm \((?:\*\*)?(\d+) %(?:\*\*)?\)", cell).groups()
        assert float(mm) == pytest.approx(row["figures"][key], abs=1e-4) and int(pct) == round(100 * row[ratio]), \
            (variant, cell, row)
    assert float(cells[5].removesuffix(" mm")) == pytest.approx(row["figures"]["steady_mean_mm"], abs=1e-4)


def test_the_modes_come_from_the_tap_test(result):
    modes = result["identified"]["modes"]
    assert [m["hz"] for m in modes] == pytest.approx([10.0, 16.0], rel=0.01)


@pytest.mark.parametrize("k", [1, 2], ids=["+20 %", "-20 %"])
def test_with_the_frequency_20_percent_off_the_robust_filter_still_gains_and_loses_nothing(result, k):
    c = result["cases"][0]
    row = c["dynamic"][k]
    assert row["options"].added_damping == ROBUST
    assert row["entry_ratio"] < 1.0 and row["exit_ratio"] < 1.0, row
    assert row["figures"]["steady_mean_mm"] <= c["static"]["steady_mean_mm"], (row, c["static"])


def reversal_split(ev: dict) -> tuple[np.ndarray, np.ndarray]:
    """|error| (mm) within the reversal windows, and elsewhere on the circle."""
    c = ev.cut
    a, e = np.degrees(ev.angle[c]), np.abs(ev.err_mm[c])
    inside = np.zeros(len(a), dtype=bool)
    for lo, hi in REVERSALS_DEG:
        inside |= (a > lo) & (a < hi)
    return e[inside], e[~inside]


def reversal_max(ev: dict) -> float:
    return float(reversal_split(ev)[0].max())


def reversal_ratio(ev: dict) -> float:
    """max |error| within the reversal windows / max |error| elsewhere on the circle."""
    inside, elsewhere = reversal_split(ev)
    return float(inside.max() / elsewhere.max())


def test_hysteresis_at_joint_1_reversals_compensated(result, tmp_path):
    truth = StiffnessModel.from_yaml(TRUTH)
    d = truth.to_dict()
    d["effects"].append({"effect": "hysteresis", "joint": 1, "offset_deg": 0.012})
    truth = StiffnessModel.from_dict(d, "truth + hysteresis@joint1", robot=truth.robot)
    path = tmp_path / "truth.yaml"
    truth.to_yaml(path)
    sc = cell_scenario()
    # the hysteresis's flips are no linear function of the force: the delay is not measured on this truth
    # (None, not a wrong figure) but given, as measured on the springs' truth of the same chain
    delay_ms = result["cases"][0]["delay_ms"]
    res = run_circle(sc, path, path, lockstep=True, dynamic=DynamicOptions(delay_ms=delay_ms), workdir=tmp_path / "runs")
    assert res.summary["delay_ms"] is None
    unc = res.summary["mean_error_mm_uncompensated"]
    inside = {}
    for name in ("compensated", "dynamic"):
        ev = res.evaluations[name]
        mean = float(np.abs(ev.err_mm[ev.cut]).mean())
        inside[name] = reversal_max(ev)
        assert mean <= 0.10 * unc, (name, mean, unc)
    static = res.evaluations["compensated"]
    assert reversal_ratio(static) <= 2.0, reversal_ratio(static)
    assert inside["dynamic"] <= inside["compensated"], inside     # the dynamic path adds no glitch of its own
    springs = evaluate_pass(sc, truth, run_lockstep(sc, truth, TRUTH, True, tmp_path / "springs"))[1]
    assert float(np.abs(springs.err_mm[springs.cut]).mean()) > 3 * res.summary["mean_error_mm_static"]
