"""Wrench transport (Eq. 2-4) agrees with pinocchio's action of SE3 on forces."""

import numpy as np
import pinocchio as pin

from stiffness.kinematics.spatial import exp_so3, log_so3, transform, transport_wrench, wrench_action_matrix


def random_pose(rng):
    return transform(exp_so3(rng.normal(size=3)), rng.normal(size=3))


def test_transport_matches_pinocchio_action():
    rng = np.random.default_rng(0)
    for _ in range(50):
        T0i, T0j = random_pose(rng), random_pose(rng)
        W = rng.normal(size=6) * [100, 100, 100, 10, 10, 10]
        ours = transport_wrench(W, T0i, T0j)
        M_ji = pin.SE3(np.linalg.inv(T0j) @ T0i)     # pose of frame i in frame j
        theirs = M_ji.act(pin.Force(W[:3], W[3:]))
        np.testing.assert_allclose(ours, np.r_[theirs.linear, theirs.angular], rtol=1e-12, atol=1e-9)
        # Eq. 3's A is pinocchio's dual action matrix
        T_ij = np.linalg.inv(T0i) @ T0j
        A = wrench_action_matrix(T_ij[:3, :3].T, T_ij[:3, 3])
        np.testing.assert_allclose(A, M_ji.toDualActionMatrix(), atol=1e-12)


def test_transport_round_trip_and_power_invariance():
    rng = np.random.default_rng(1)
    T0i, T0j = random_pose(rng), random_pose(rng)
    W = rng.normal(size=(10, 6))
    back = transport_wrench(transport_wrench(W, T0i, T0j), T0j, T0i)
    np.testing.assert_allclose(back, W, atol=1e-12)
    # the power of a wrench on a rigid motion is frame independent
    v_i = rng.normal(size=6)
    v_j = pin.SE3(np.linalg.inv(T0j) @ T0i).act(pin.Motion(v_i[:3], v_i[3:]))
    Wj = transport_wrench(W[0], T0i, T0j)
    assert np.isclose(W[0] @ v_i, Wj @ np.r_[v_j.linear, v_j.angular])


def test_rotation_vector_round_trip():
    r = np.random.default_rng(2).normal(size=(100, 3)) * 0.5
    np.testing.assert_allclose(log_so3(exp_so3(r)), r, atol=1e-12)
