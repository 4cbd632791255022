"""The discovery loop closes in the compensation (issue 11), for hysteresis at joint 2, bending of
link 2 and a 3 deg sensor misalignment: the robot stub's truth is the reference truth plus the effect;
a campaign simulated from it with the reference protocol (examples/campaign_reference.yaml) makes
`diagnose`, from the 6-DoF springs model, name the effect at its place; added and fitted, it goes to
the service, in lock step (`hil.lockstep`: the service's own cycle with the virtual sensor and PLC, the
figures the model's and not the host's; the real-time road is test_hil_closed_loop's). On the circle, against the uncompensated path error (the truth's deflection along the
nominal path, `hil.report.evaluate_uncompensated`: no process is needed for it), the exact model (the truth)
leaves at most 10 % of the uncompensated mean path error, and both the exact and the fitted model
leave less than the springs-only model fitted to the same campaign.

The circle is the paper's (35 mm, the scenario's milling) on a lower table than config/hil/circle.yaml's:
there the TCP is level with joint 2, so a turn of joint 2 (its hysteresis) moves the tool up and down,
off the path error, and joint 2's torque hardly changes along the circle; 0.55 m below joint 2 each of
the three effects moves the tool in the circle's plane.
"""

from __future__ import annotations

import pytest

from hil.report import evaluate_uncompensated
from hil.robot_stub import RobotStub
from hil.testing import truth_with
from hil.world import World
from stiffness.diagnose.discovery import diagnose
from stiffness.files.yaml_schema import read_yaml
from stiffness.fit.identify import fit
from stiffness.model.edit import add_effect
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.plan.simulate import Campaign, CampaignSpec
from testlib.hil import EXAMPLES, MODELS, compensated, mean_error, scenario, write_model

LOW_TABLE_Q_DEG = [0.0, -45.0, 100.0, 0.0, 35.0, 0.0]     # tool down, TCP 0.55 m below joint 2

# Sizes that matter on the circle beyond the HIL's own floor (~0.01 mm with the exact model): a
# hysteresis offset of half a typical 1 arcmin lost motion; link 2 softer than tests/discovery's 2e-7,
# which the springs-only fit absorbs all but 0.01 mm of; the sensor turned about its axis (the tool's,
# vertical here), which turns the feed and normal forces into each other in the circle's plane.
CASES = [
    # (id, the effect in the truth, what the diagnosis must name)
    ("hysteresis-j2", {"effect": "hysteresis", "joint": 2, "offset_deg": -0.008, "transition_Nm": 40}, ("hysteresis", 2)),
    ("bending-link2", {"effect": "link_bending", "link": 2, "compliance_per_Nm2": 5.0e-7}, ("link_bending", 2)),
    ("misalignment-rz3", {"effect": "sensor_misalignment", "rz_deg": 3.0}, ("sensor_misalignment", None)),
]


def reference_campaign(truth: StiffnessModel) -> Campaign:
    """examples/campaign_reference.yaml's protocol on ``truth``."""
    spec = CampaignSpec.model_validate(read_yaml(EXAMPLES / "campaign_reference.yaml"))
    return Campaign(spec, truth, f"campaign_reference on {truth.source}")


@pytest.mark.parametrize("entry, expected", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_fitted_effect_compensates_better_than_springs_alone(entry, expected, tmp_path):
    truth = truth_with([entry])
    data = reference_campaign(truth).run()
    d = diagnose(StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml"), data)
    assert d.verdict == "missing_effect", d.message
    assert (d.best.name, d.best.joint) == expected, [(c.name, c.joint, c.cv_improvement) for c in d.candidates[:3]]
    # bounded fits: the service refuses a model with a negative compliance (an unbounded fit leaves some)
    fitted = fit(add_effect(d.fit.model, d.best.name, d.best.joint), data, nonnegative=True)
    assert fitted.converged, fitted.message
    truth_path = write_model(truth, tmp_path / "truth.yaml")
    springs = fit(d.fit.model, data, nonnegative=True).model
    models = {"exact": truth_path, "fitted": write_model(fitted.model, tmp_path / "fitted.yaml"),
              "springs-only": write_model(springs, tmp_path / "springs.yaml")}
    sc = scenario(center_q_deg=LOW_TABLE_Q_DEG)
    stub = RobotStub(truth, sc.robot)
    e = {"uncompensated": mean_error(evaluate_uncompensated(World(sc, truth.robot), stub, sc.plc.period_ms / 1e3))}
    for name, path in models.items():
        e[name] = mean_error(compensated(sc, truth_path, path, tmp_path / name, lockstep=True)[1])
    print(entry["effect"], {k: round(v, 4) for k, v in e.items()}, "mm")
    assert e["uncompensated"] > 0.2, e                   # the process force deflects the robot
    assert e["exact"] <= 0.10 * e["uncompensated"], e
    assert e["exact"] < e["springs-only"], e
    assert e["fitted"] < e["springs-only"], e
