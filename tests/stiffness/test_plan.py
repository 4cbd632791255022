"""`stiffcomp plan` (issue 12): optimal configurations beat random ones, and what they predict holds.

* The plan's worst predicted relative standard error of the rotational compliances (36-parameter
  model, 6-D optical device, N = 4) is clearly below the median of random sets of 4 configurations.
* A campaign simulated from the plan's YAML and fitted gives standard errors within 25 % of the
  predicted ones.
* A tracker plan names joint 6's axial compliance (TCP on its axis) and writes a TCP-position campaign.
"""

import re

import numpy as np
import pytest
import yaml

from stiffness.fit.identify import fit
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.plan.design import Device, worst_relative
from stiffness.plan.design import plan as make_plan
from stiffness.plan.simulate import Campaign, random_configurations
from testlib.common import MODELS, ROOT
from tools.cli import main

pytestmark = pytest.mark.slow

N = 4


@pytest.fixture(scope="module")
def model():
    return StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml")


@pytest.fixture(scope="module")
def planned(tmp_path_factory, model):
    out = tmp_path_factory.mktemp("plan") / "plan.yaml"
    assert main(["plan", str(MODELS / "kr125_6dof.yaml"), "--configurations", str(N), "-o", str(out)]) == 0
    return out, make_plan(model, Device.named("optical6d", model), N, seed=0)


def test_plan_beats_random_configurations(model, planned):
    _, p = planned
    rotational = np.array([lab.split(".")[-1].startswith("r") for lab in p.labels])
    np.testing.assert_array_equal(p.interest, rotational)
    device = Device.named("optical6d", model)
    ours = worst_relative(model, device, p.q_deg, rotational)
    assert ours == pytest.approx(p.criterion, rel=1e-3)
    robot = model.robot
    random = [worst_relative(model, device, random_configurations(robot, N, 100 + s, 10.0), rotational)
              for s in range(15)]
    assert ours < 0.8 * np.median(random), (ours, np.median(random))
    lo, hi = robot.limits_deg[:, 0] + 10.0 - 1e-9, robot.limits_deg[:, 1] - 10.0 + 1e-9
    assert ((p.q_deg >= lo) & (p.q_deg <= hi)).all()


def test_plan_md_states_the_ratio_to_random_sets_the_plan_gives(planned):
    """docs/plan.md's figure: the plan's criterion over the median of random sets of N, to two digits."""
    _, p = planned
    said = re.search(r"is (?:about )?([\d.]+) × the median of random sets of (\d+) configurations",
                     " ".join((ROOT / "docs" / "plan.md").read_text().split()))
    assert said and int(said.group(2)) == N
    assert float(said.group(1)) == round(p.criterion / p.random_median, 2), (p.criterion, p.random_median)


def test_simulated_plan_fits_with_the_predicted_std_errors(model, planned):
    path, p = planned
    doc = yaml.safe_load(path.read_text())
    np.testing.assert_allclose([c["q_deg"] for c in doc["configurations"]], p.q_deg, atol=1e-9)
    data = Campaign.from_yaml(path).run()
    result = fit(model, data)
    ratio = result.std_error[p.interest] / p.std_error[p.interest]
    assert np.all(np.abs(ratio - 1) < 0.25), dict(zip(np.array(p.labels)[p.interest], ratio.round(3)))


def test_tracker_plan_names_joint6_axial_and_writes_tcp_positions(tmp_path, model):
    out = tmp_path / "tracker.yaml"
    assert main(["plan", str(MODELS / "kr125_axial.yaml"), "-n", "3", "--device", "tracker", "-o", str(out),
                 "--json"]) == 0
    doc = yaml.safe_load(out.read_text())
    assert doc["bodies"] == ["TCP"] and doc["components"] == ["dx", "dy", "dz"]
    data = Campaign.from_yaml(out).run()
    assert data.measured[:, :3].all() and not data.measured[:, 3:].any()
    axial = StiffnessModel.from_yaml(MODELS / "kr125_axial.yaml")
    p = make_plan(axial, Device.named("tracker", axial), 3)
    assert p.unidentifiable == ["joint_spring@joint6.rz_rad_per_Nm"]
    assert np.isfinite(p.std_error[:5]).all() and np.isinf(p.std_error[5])
