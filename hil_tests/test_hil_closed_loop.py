"""The closed loop cuts the path error of the paper's circle (Fig. 8): the service, the virtual sensor
and the virtual PLC in separate processes, in real time, twice on the same force trace.

Properties: with the truth itself as the model the mean path error falls by >= 90 %; with a model
identified from a simulated campaign by >= 75 %. Both passes see the same process force, and nothing
is written outside the register map.
"""

from __future__ import annotations

import numpy as np

from hil.circle import run_circle
from stiffness.fit.identify import fit
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.plan.simulate import Campaign
from testlib.hil import EXAMPLES, MODELS, OUT, nothing_outside_the_map, scenario, write_model

TRUTH = EXAMPLES / "truth_reference.yaml"


def reduction(summary: dict) -> float:
    return 1.0 - summary["mean_error_mm"] / summary["mean_error_mm_uncompensated"]


def test_exact_model_cuts_the_mean_path_error_by_90_percent(tmp_path):
    res = run_circle(scenario(), TRUTH, TRUTH, report=tmp_path / "report", workdir=tmp_path / "run")
    s = res.summary
    assert s["mean_error_mm_uncompensated"] > 0.2, s          # the process force deflects the robot
    assert reduction(s) >= 0.90, s
    assert s["max_error_mm"] < s["max_error_mm_uncompensated"], s
    assert s["cycles"] > 1000
    assert (tmp_path / "report" / "hil_circle.png").stat().st_size > 10_000
    for r in res.passes.values():
        assert nothing_outside_the_map(r) == []
    # the same force trace in both passes: the wrench the service filtered agrees between them
    u, c = res.passes["uncompensated"].log, res.passes["compensated"].log
    k = OUT.index("wrench_fx")
    fx_u = np.interp(c.t, u.t, u.to_plc[:, k])
    cut = (c.t > 0.3) & (c.t < res.world.path.duration)
    assert np.abs(fx_u - c.to_plc[:, k])[cut].mean() < 0.05 * np.abs(fx_u[cut]).mean()


def test_model_identified_from_a_simulated_campaign_cuts_it_by_75_percent(tmp_path):
    data = Campaign.from_yaml(EXAMPLES / "campaign_reference.yaml").run()
    # bounded: the service refuses a model with a negative compliance (an unbounded fit leaves some)
    fitted = fit(StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml"), data, nonnegative=True)
    assert fitted.converged, fitted.message
    model = write_model(fitted.model, tmp_path / "identified.yaml")
    s = run_circle(scenario(), TRUTH, model, workdir=tmp_path / "run").summary
    assert reduction(s) >= 0.75, s
