"""The spring model's properties and the conformance check against the reference campaign."""

from pathlib import Path

import numpy as np
import pytest
import yaml

from stiffness.data.measurements import read_measurements
from stiffness.effects.joint_spring import COMPONENTS
from stiffness.fit.identify import fit
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import DATA, MODELS, random_dataset, with_deflection


def random_compliances(model, seed):
    rng = np.random.default_rng(seed)
    theta = model.theta.copy()
    return theta * rng.uniform(0.5, 1.5, size=theta.shape)


def test_zero_load_gives_zero_deflection(robot, model6):
    data = random_dataset(robot, 30, seed=3)
    data.wrench[:] = 0.0
    assert np.abs(model6.predict(data)).max() < 1e-12


def _scaled(data, k):
    out = data.subset(np.arange(len(data)))
    out.wrench = data.wrench * k
    return out


def test_deflection_is_linear_in_the_load(robot, model6):
    """Linear to first order: d(-W) = -d(W), and the departure from d(kW) = k d(W) is the second-order
    term of composing finite rotations: relative to the deflection it is of the order of the largest
    rotation (rad), and it halves, relative to the deflection, when the load halves."""
    data = random_dataset(robot, 40, seed=4, max_force=1200.0)
    d1 = model6.predict(data)
    scale = np.abs(d1).max(axis=0)
    lin = model6.predict(data, linear=True)
    dev1 = np.abs(d1 - lin).max(axis=0) / scale
    max_rotation_rad = np.radians(scale[3:].max())
    assert dev1.max() < max_rotation_rad < 0.02
    d_half = model6.predict(_scaled(data, 0.5))
    dev_half = np.abs(d_half - 0.5 * lin).max(axis=0) / (0.5 * scale)
    np.testing.assert_allclose(dev_half[:3] / dev1[:3], 0.5, rtol=0.1)  # relative error halves
    dm = model6.predict(_scaled(data, -1.0))
    # odd part: the linear map; even part: exactly twice the second-order term
    np.testing.assert_allclose((d1 - dm) / 2, lin, atol=1e-4 * scale.max())
    np.testing.assert_allclose((d1 + dm) / 2, d1 - lin, atol=1e-4 * scale.max())
    np.testing.assert_allclose(lin, -model6.predict(_scaled(data, -1.0), linear=True), atol=1e-12)


def test_a_spring_moves_only_the_bodies_beyond_it(robot, model6):
    data = random_dataset(robot, 10, seed=5)
    m = model6.copy()
    theta = np.zeros_like(m.theta)
    theta[4 * 6 + COMPONENTS.index("rz")] = 1e-6   # joint 5's axial spring only
    d = m.predict(data, theta)
    before = data.body < 4                          # A1..A4 do not move
    assert np.abs(d[before]).max() == 0.0
    assert (np.abs(d[~before]).max(axis=1) > 0).all()  # A5, A6 and the TCP move in every reading
    assert np.abs(d[data.body == 6]).max() > 1e-3


def test_known_parameters_are_recovered(robot, model6):
    """Data made with known compliances, no noise: the fit returns them."""
    data = random_dataset(robot, 120, seed=6)
    truth = random_compliances(model6, 7)
    data = with_deflection(data, model6.predict(data, truth))
    result = fit(model6, data)
    np.testing.assert_allclose(result.model.theta, truth, rtol=1e-6, atol=1e-14)
    assert result.rms_position_mm < 1e-6


def test_reference_campaign_conformance():
    """The conventions of issue 2 item 3: fitting kr125_6dof recovers the reference truth."""
    truth = yaml.safe_load((DATA / "reference_truth.yaml").read_text())
    model = StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml")
    data = read_measurements(DATA / "reference_campaign.csv", model.robot)
    result = fit(model, data)
    for e, tr in zip(result.model.effects, truth["springs"]["compliance"]):
        assert e.joint == tr["joint"]
        est = dict(zip([p.key for p in e.params], e.theta))
        assert est["rz_rad_per_Nm"] == pytest.approx(tr["rz_rad_per_Nm"], rel=0.03)
        assert est["rx_rad_per_Nm"] == pytest.approx(tr["rx_rad_per_Nm"], rel=0.20)
        assert est["ry_rad_per_Nm"] == pytest.approx(tr["ry_rad_per_Nm"], rel=0.20)
    noise = truth["noise_sigma"]
    assert result.rms_position_mm == pytest.approx(noise["position_mm"], rel=0.10)
    assert result.rms_rotation_deg == pytest.approx(noise["rotation_deg"], rel=0.10)
    # the translational compliances sit below the noise (as in the paper) and are flagged
    assert all(any(lab.endswith(f"joint{j}.{c}_m_per_N") for lab in result.undetermined)
               for j in range(1, 7) for c in "xyz")
    assert not any("_rad_per_Nm" in lab for lab in result.undetermined)


def test_axial_model_is_worse_than_6dof_on_reference():
    data = read_measurements(DATA / "reference_campaign.csv")
    r6 = fit(StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml"), data)
    ra = fit(StiffnessModel.from_yaml(MODELS / "kr125_axial.yaml"), data)
    assert ra.rms_rotation_deg > 2 * r6.rms_rotation_deg


def test_fitted_model_yaml_round_trip(tmp_path, robot, model6):
    data = random_dataset(robot, 50, seed=8)
    data = with_deflection(data, model6.predict(data, random_compliances(model6, 9)))
    fitted = fit(model6, data).model
    out = tmp_path / "deeper" / "fitted.yaml"          # written far from config/models: the robot is found
    out.parent.mkdir()
    fitted.to_yaml(out)
    again = StiffnessModel.from_yaml(out)
    np.testing.assert_allclose(again.theta, fitted.theta, rtol=1e-5)
    assert Path(again.robot.source).resolve() == Path(model6.robot.source).resolve()
