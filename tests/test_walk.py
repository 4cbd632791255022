"""The README's discovery walk, end to end on the shipped example campaign, as a user runs it."""

import json

import pytest

from testlib.common import ROOT, run_cli

pytestmark = pytest.mark.slow

DATA = ROOT / "examples" / "campaign_backlash.csv"


def stiffcomp(*args):
    r = run_cli(*args)
    assert r.returncode == 0, r.stderr
    return r


def test_compare_diagnose_add_fit_compare(tmp_path):
    base = tmp_path / "6dof.yaml"
    stiffcomp("fit", ROOT / "config/models/kr125_6dof.yaml", DATA, "-o", base)
    diag = json.loads(stiffcomp("diagnose", base, DATA, "--json", "--report", tmp_path / "diagnose").stdout)
    assert diag["verdict"] == "missing_effect"
    best = diag["candidates"][0]
    assert (best["effect"], best["joint"]) == ("backlash", 3) and best["significant"]
    assert set(diag["worst"]) >= {"body", "component", "config"}
    assert all(0.0 <= c["cv_improvement"] <= 1.0 for c in diag["candidates"])
    assert [c["cv_improvement"] for c in diag["candidates"] if c["significant"]] == sorted(
        [c["cv_improvement"] for c in diag["candidates"] if c["significant"]], reverse=True)
    html = (tmp_path / "diagnose" / "index.html").read_text()
    assert "missing_effect" in html and (tmp_path / "diagnose" / "evidence.png").stat().st_size > 10_000
    added = tmp_path / "6dof_backlash.yaml"
    stiffcomp("model", "add", base, "backlash", "--joint", "3", "-o", added)
    fitted = tmp_path / "6dof_backlash_fitted.yaml"
    stiffcomp("fit", added, DATA, "-o", fitted)
    cmp = json.loads(stiffcomp("compare", base, fitted, DATA, "--json").stdout)
    before, after = cmp["models"][0], cmp["models"][1]
    assert after["rms_position_mm"] < 0.8 * before["rms_position_mm"]
    assert after["rms_rotation_deg"] < 0.8 * before["rms_rotation_deg"]
    assert after["rms_position_mm"] < 1.15 * 0.03
    again = json.loads(stiffcomp("diagnose", fitted, DATA, "--json").stdout)
    assert again["verdict"] == "no_missing_effect"


def test_walk_starts_with_a_plan_that_simulate_runs(tmp_path):
    """The README walk's first step: plan 4 configurations, rehearse the plan with simulate, fit it."""
    plan = tmp_path / "plan.yaml"
    out = json.loads(stiffcomp("plan", ROOT / "config/models/kr125_6dof.yaml", "--configurations", "4",
                               "-o", plan, "--json").stdout)
    assert len(out["configurations"]) == 4 and out["criterion"] < out["random_median"]
    assert len(out["parameters"]) == 36
    data = tmp_path / "plan.csv"
    stiffcomp("simulate", plan, "-o", data)
    fitted = json.loads(stiffcomp("fit", ROOT / "config/models/kr125_6dof.yaml", data, "--json").stdout)
    assert fitted["outliers"]["count"] <= 2 and fitted["unidentifiable"] == []
