"""The prior of a fit (`stiffness.model.prior`) and rows measured in axes of their own (`Dataset.axes`): what a part's
learning rests on (issue 29, item 5)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from stiffness.data.measurements import read_measurements
from stiffness.errors import ConfigError
from stiffness.fit.identify import fit
from stiffness.model.prior import Prior
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import DATA


@pytest.fixture(scope="module")
def campaign():
    return read_measurements(DATA / "reference_campaign.csv")


@pytest.fixture(scope="module")
def fitted(model6, campaign):
    return fit(model6, campaign)


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), unknown=st.integers(0, 3))
def test_the_prior_rows_hold_exactly_its_information(seed, unknown):
    """R^T R is the inverse covariance over the parameters it knows; one of infinite variance gets no row."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(5, 5))
    corr = A @ A.T + 0.1 * np.eye(5)                       # correlated, conditioned as a fit's are
    corr /= np.sqrt(np.outer(np.diag(corr), np.diag(corr)))
    sd = np.exp(rng.uniform(-20, 3, 5))                     # parameters of very different scales
    cov = corr * np.outer(sd, sd)
    cov[unknown, :] = cov[:, unknown] = 0.0
    cov[unknown, unknown] = np.inf
    prior = Prior(list("abcde"), rng.normal(size=5), cov, "random")
    R, c = prior.rows(list("abcde"))
    known = [k for k in range(5) if k != unknown]
    np.testing.assert_allclose((R.T @ R)[np.ix_(known, known)], np.linalg.inv(cov[np.ix_(known, known)]),
                               rtol=1e-6, atol=1e-9 * np.abs(np.linalg.inv(cov[np.ix_(known, known)])).max())
    assert not R[:, unknown].any() and R.shape[0] == 4
    np.testing.assert_allclose(c, R @ prior.mean)


def test_fit_stores_its_covariance_and_a_yaml_round_trip_gives_it_back(fitted, tmp_path):
    path = tmp_path / "fitted.yaml"
    fitted.model.to_yaml(path)
    again = StiffnessModel.from_yaml(path)
    prior = Prior.from_model(again)
    labels = again.param_labels()
    np.testing.assert_allclose(prior.std(labels), fitted.std_error, rtol=1e-5)
    sd = np.sqrt(np.diag(fitted.covariance))
    np.testing.assert_allclose(prior.covariance, fitted.covariance, atol=1e-6 * np.outer(sd, sd).max(),
                               rtol=1e-5)


def test_half_a_campaign_with_the_whole_ones_prior_knows_what_both_halves_know(model6, campaign, fitted):
    """Information adds: the whole campaign's fit as the prior of one half shrinks the half's standard errors
    by 1/sqrt(3) (the prior holds twice the half's information), and moves no estimate by more than its
    standard error."""
    half = campaign.subset(np.arange(len(campaign)) % 2 == 0)
    alone = fit(model6, half)
    both = fit(fitted.model, half, prior=Prior.from_fit(fitted, "the whole campaign"))
    ratio = both.std_error / alone.std_error
    assert np.median(ratio) == pytest.approx(1 / np.sqrt(3.0), rel=0.05)
    assert np.max(np.abs(both.model.theta - fitted.model.theta) / fitted.std_error) < 1.0


def test_a_prior_the_data_do_not_see_holds_the_parameters_where_it_is(model6, campaign):
    """Only the TCP's position measured: joint 6's axial compliance moves nothing measured, so with a prior it
    stays exactly at the prior's mean, and is not reported unidentifiable."""
    tcp = campaign.subset(np.nonzero(campaign.body == 6)[0])
    tcp.deflection[:, 3:] = np.nan
    prior = Prior.catalogue(model6, 0.5)
    r = fit(model6, tcp, prior=prior)
    k = model6.param_labels().index("joint_spring@joint6.rz_rad_per_Nm")
    assert r.model.theta[k] == pytest.approx(model6.theta[k], rel=1e-9)
    assert "joint_spring@joint6.rz_rad_per_Nm" not in r.unidentifiable
    assert r.std_error[k] == pytest.approx(prior.std(model6.param_labels())[k], rel=1e-3)


def test_rows_measured_in_axes_of_their_own_fit_as_in_base_axes(model6, campaign):
    """Invariance: every row's deflection given in axes of its own (turned at random) fits to the same model."""
    data = campaign.subset(np.arange(0, len(campaign), 5))
    A = Rotation.random(len(data), random_state=3).as_matrix()
    turned = data.subset(np.arange(len(data)))
    turned.axes = A
    turned.deflection = np.concatenate([np.einsum("nij,nj->ni", A, data.deflection[:, :3]),
                                        np.einsum("nij,nj->ni", A, data.deflection[:, 3:])], axis=1)
    np.testing.assert_allclose(model6.predict(turned)[:, :3], np.einsum("nij,nj->ni", A, model6.predict(data)[:, :3]),
                               rtol=1e-9, atol=1e-12)
    a, b = fit(model6, data, robust=False), fit(model6, turned, robust=False)
    np.testing.assert_allclose(b.model.theta, a.model.theta, rtol=1e-8)


@pytest.mark.parametrize("edit, match", [
    (lambda c: c.pop("correlation"), "params, std_error and correlation"),
    (lambda c: c.update(std_error=c["std_error"][:-1]), r"std_error must list 36 numbers"),
    (lambda c: c.update(correlation=[[2.0] * 36] * 36), "symmetric 36 x 36 matrix of numbers in"),
    (lambda c: c.update(colour="red"), r"covariance.colour is not a known key"),
])
def test_a_bad_covariance_in_a_model_yaml_is_named(fitted, edit, match):
    d = fitted.model.to_dict()
    d["covariance"] = {k: (list(v) if isinstance(v, list) else v) for k, v in d["covariance"].items()}
    edit(d["covariance"])
    with pytest.raises(ConfigError, match=f"m.yaml: {'' if 'covariance' in match else 'covariance'}.*{match}"):
        StiffnessModel.from_dict(d, "m.yaml", robot=fitted.model.robot)
