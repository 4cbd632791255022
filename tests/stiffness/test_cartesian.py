"""Cartesian stiffness at the TCP: W = K dX round trips, and Eq. 15 identifies K from TCP data."""

import numpy as np

from stiffness.data.measurements import Dataset
from stiffness.kinematics.spatial import transform, transport_wrench
from stiffness.model.cartesian import (
    identify_cartesian,
    tcp_compliance,
    tcp_stiffness,
    tcp_wrench_and_deflection,
)
from testlib.common import with_deflection

Q = np.array([10.0, -75.0, 90.0, 0.0, 75.0, 0.0])


def tcp_dataset(robot, W_tcp, q=Q):
    """Readings that load the TCP with the wrenches W_tcp (base axes, about the TCP)."""
    n = len(W_tcp)
    F = robot.frames(np.radians(q)[None])
    T_tcp = transform(np.eye(3), F[0, 7, :3, 3])
    W_sensor = transport_wrench(W_tcp, T_tcp[None], robot.sensor_pose(F))
    return Dataset(np.arange(n, dtype=float), np.array(["C"] * n), np.tile(q, (n, 1)), W_sensor,
                   np.full(n, 6), np.zeros((n, 6)))


def test_w_equals_k_dx_round_trip(robot, model6):
    K = tcp_stiffness(model6, Q)
    C = tcp_compliance(model6, Q)
    np.testing.assert_allclose(K @ C, np.eye(6), atol=1e-9)
    W = np.random.default_rng(0).normal(size=(8, 6)) * [500, 500, 500, 50, 50, 50]
    dX = model6.predict(tcp_dataset(robot, W))
    dX_si = np.c_[dX[:, :3] / 1000, np.radians(dX[:, 3:])]
    np.testing.assert_allclose(dX_si @ K.T, W, rtol=1e-4, atol=1e-3 * np.abs(W).max())


def test_compliance_is_symmetric_for_springs(model6):
    """Conservative springs give a symmetric compliance (Maxwell-Betti)."""
    C = tcp_compliance(model6, Q)
    np.testing.assert_allclose(C, C.T, atol=1e-6 * np.abs(C).max())


def test_eq15_identifies_k_from_tcp_data(robot, model6):
    W = np.random.default_rng(1).normal(size=(60, 6)) * [50, 50, 50, 5, 5, 5]  # linear regime
    data = tcp_dataset(robot, W)
    data = with_deflection(data, model6.predict(data))
    W_back, dX = tcp_wrench_and_deflection(data, robot)
    np.testing.assert_allclose(W_back, W, atol=1e-9)
    K = identify_cartesian(W_back, dX)
    np.testing.assert_allclose(K, tcp_stiffness(model6, Q), rtol=1e-3, atol=1e-3 * np.abs(K).max())


def test_history_and_time_do_not_enter_k(robot, model6):
    """The probes are independent readings at time 0: hysteresis and drift leave C unchanged."""
    from stiffness.model.edit import add_effect
    m = add_effect(add_effect(model6, "hysteresis", 2, {"offset_deg": 0.005}), "drift", None, {"x_mm_per_min": 0.1})
    np.testing.assert_allclose(tcp_compliance(m, Q), tcp_compliance(model6, Q), rtol=1e-9, atol=1e-15)


def test_eq15_refuses_wrenches_that_do_not_span_six_directions(robot, model6):
    """Forces at one load point give moments r x F in a plane: K is not identifiable from them."""
    rng = np.random.default_rng(2)
    F = rng.normal(size=(40, 3)) * 500
    W = np.c_[F, np.cross([0.1, 0.0, 0.0], F)]
    data = tcp_dataset(robot, W)
    data = with_deflection(data, model6.predict(data))
    W_back, dX = tcp_wrench_and_deflection(data, robot)
    import pytest
    with pytest.raises(ValueError, match="do not span six directions"):
        identify_cartesian(W_back, dX)


def test_singular_compliance_is_refused():
    import pytest

    from stiffness.model.stiffness_model import StiffnessModel
    from testlib.common import MODELS
    axial = StiffnessModel.from_yaml(MODELS / "kr125_axial.yaml")
    with pytest.raises(ValueError, match="singular"):
        tcp_stiffness(axial, np.array([10.0, -75.0, 90.0, 0.0, 0.0, 0.0]))   # q5 = 0: a wrist singularity


def test_eq15_refuses_moments_that_are_only_noise(robot, model6):
    """Forces at one lever plus sensor noise on the moments (the walk's campaign): the noise must not
    pass for a load direction, as it did when each column was scaled to unit RMS."""
    import pytest
    rng = np.random.default_rng(3)
    F = rng.normal(size=(150, 3)) * 700
    W = np.c_[F, np.cross([0.0, 0.0, 0.1], F) + rng.normal(size=(150, 3)) * 0.3]
    data = tcp_dataset(robot, W)
    data = with_deflection(data, model6.predict(data) + rng.normal(size=(150, 6)) * ([0.03] * 3 + [0.002] * 3))
    W_back, dX = tcp_wrench_and_deflection(data, robot)
    with pytest.raises(ValueError, match=r"load's lever \(0\.0[89]\d* m\)"):
        identify_cartesian(W_back, dX)


def test_eq15_refuses_a_k_that_is_not_positive_definite():
    import pytest
    rng = np.random.default_rng(4)
    W = rng.normal(size=(60, 6)) * [500, 500, 500, 50, 50, 50]
    C = np.diag([1e-6, 1e-6, -1e-6, 1e-5, 1e-5, 1e-5])            # a spring pushing the wrong way along z
    with pytest.raises(ValueError, match=r"not positive definite \(its symmetric part has eigenvalue\(s\) -1e\+06"):
        identify_cartesian(W, W @ C.T)
    np.testing.assert_allclose(identify_cartesian(W, W @ np.abs(C).T), np.linalg.inv(np.abs(C)), rtol=1e-6, atol=1e-3)


def test_kcart_refuses_the_walks_campaign_and_says_why():
    import subprocess
    import sys

    from testlib.common import MODELS, ROOT
    r = subprocess.run([sys.executable, "-m", "tools.cli", "kcart", MODELS / "kr125_6dof.yaml", "--data",
                        ROOT / "examples" / "campaign_backlash.csv"], cwd=ROOT, capture_output=True, text=True,
                       check=False, timeout=180)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    assert len(lines) == 5 and all("refused: the wrenches do not span six directions" in x for x in lines)
