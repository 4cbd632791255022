"""The static joint torque tau_s(q) is signed exactly like the model's external joint torque W_i[rz]."""

from __future__ import annotations

import numpy as np
import pinocchio as pin
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stiffness.data.campaign import Context
from stiffness.data.measurements import Dataset
from stiffness.effects.axial import joint_torque
from stiffness.files.yaml_schema import dump_yaml
from stiffness.kinematics.robot import Robot, read_extended
from stiffness.kinematics.spatial import transform, transport_wrench
from stiffness.kinematics.statics import G_STANDARD, Statics, independent_columns
from testlib.common import ROOT

KR125 = ROOT / "config" / "robots" / "kr125_masses.yaml"
G = np.array(G_STANDARD)


@pytest.fixture(scope="module")
def robot() -> Robot:
    """The KR 125 with its shipped masses and balancer (the kinematic kr125.yaml has none)."""
    return Robot.from_yaml(KR125)


def robot_with(tmp_path, inertial: dict | None, sensor: dict | None = None) -> Robot:
    """The KR 125 with the given inertial section (None: no masses) and optionally another sensor pose."""
    doc = read_extended(KR125)
    doc.pop("inertial", None)
    if inertial is not None:
        doc["inertial"] = inertial
    if sensor is not None:
        doc["sensor"] = sensor
    path = tmp_path / f"r{len(list(tmp_path.iterdir()))}.yaml"
    path.write_text(dump_yaml(doc))
    return Robot.from_yaml(path)


def one_mass(link: int, mass: float, com_mm) -> dict:
    links = [{"mass_kg": 0.0, "com_mm": [0.0, 0.0, 0.0]} for _ in range(6)]
    links[link - 1] = {"mass_kg": mass, "com_mm": list(com_mm)}
    return {"links": links}


def random_q(robot: Robot, n: int, seed: int) -> np.ndarray:
    lo, hi = np.radians(robot.limits_deg).T
    return np.random.default_rng(seed).uniform(lo, hi, size=(n, 6))


def campaign_at(q: np.ndarray, wrench_sensor: np.ndarray) -> Dataset:
    """One reading per configuration, the given sensor wrench, body TCP (the deflection is not used)."""
    n = len(q)
    return Dataset(time_s=np.arange(n, dtype=float), config=np.array([f"C{k}" for k in range(n)]),
                   q_deg=np.degrees(q), wrench=wrench_sensor, body=np.full(n, 6), deflection=np.zeros((n, 6)))


@settings(max_examples=30, deadline=None)
@given(link=st.integers(1, 6), mass=st.floats(1.0, 500.0),
       com=st.lists(st.floats(-600.0, 600.0), min_size=3, max_size=3), seed=st.integers(0, 2**16))
def test_point_mass_torque_is_its_weight_as_an_external_wrench(tmp_path_factory, link, mass, com, seed):
    """A point mass on link k: tau_s = -g(q) equals W_i[rz] of its weight [m g; 0] at the mass,
    transported to DH frame i-1 by the model's own Eq. 4, for the joints i <= k that carry it; zero beyond."""
    robot = robot_with(tmp_path_factory.mktemp("r"), one_mass(link, mass, com))
    q = random_q(robot, 8, seed)
    tau = Statics(robot)(q)
    F = robot.frames(q)
    T_mass = F[:, link] @ transform(np.eye(3), np.asarray(com) / 1000.0)     # the point, in DH frame k's axes
    R = F[:, link, :3, :3]
    weight_local = np.concatenate([np.einsum("nji,j->ni", R, mass * G), np.zeros((len(q), 3))], axis=1)
    W = np.stack([transport_wrench(weight_local, T_mass, F[:, f]) for f in range(7)], axis=1)   # (R, 7, 6)
    expected = np.stack([joint_torque(W, i) if i <= link else np.zeros(len(q)) for i in range(1, 7)], axis=1)
    np.testing.assert_allclose(tau.arm, expected, rtol=1e-9, atol=1e-9 * mass * 9.81)
    np.testing.assert_allclose(tau.total, tau.arm)          # no balancer, no payload
    # and it is minus pinocchio's generalized gravity, the torque the motors hold
    pm = robot.pin_model
    pd = pm.createData()
    np.testing.assert_allclose(tau.arm[0], -pin.computeGeneralizedGravity(pm, pd, q[0]), rtol=1e-12, atol=1e-9)


@settings(max_examples=20, deadline=None)
@given(mass=st.floats(0.5, 300.0), cog=st.lists(st.floats(-400.0, 400.0), min_size=3, max_size=3),
       sensor_frame=st.integers(1, 6), seed=st.integers(0, 2**16))
def test_payload_torque_is_the_model_s_external_torque_of_its_weight(tmp_path_factory, mass, cog, sensor_frame, seed):
    """The payload's weight as the sensor reads it ([m R_s^T g; c x F], service/gravity.py) put into the
    model's Context as an external wrench gives W_i[rz] = tau_payload at every joint."""
    sensor = {"frame": sensor_frame, "xyz_mm": [20.0, -10.0, 80.0], "rpy_deg": [10.0, -20.0, 30.0]}
    robot = robot_with(tmp_path_factory.mktemp("r"), None, sensor)
    q = random_q(robot, 8, seed)
    tau = Statics(robot, mass, cog)(q)
    R_s = robot.sensor_pose(robot.frames(q))[:, :3, :3]
    f = np.einsum("nji,j->ni", R_s, mass * G)
    wrench = np.concatenate([f, np.cross(np.asarray(cog) / 1000.0, f)], axis=1)
    ctx = Context(robot, campaign_at(q, wrench))
    expected = np.stack([joint_torque(ctx.frame_wrench, i) for i in range(1, 7)], axis=1)
    expected[:, sensor_frame:] = 0.0             # joints beyond the sensor's link do not carry it
    np.testing.assert_allclose(tau.payload, expected, rtol=1e-9, atol=1e-9 * mass * 9.81)
    assert not tau.arm.any() and not tau.balancer.any()


def test_hand_worked_example_home_pose(tmp_path):
    """At q = 0 the arm is stretched along base +x and joint 2's axis z_1 is base +y (Rx(-90)). 100 kg
    at 500 mm beyond joint 2 along +x: the moment of its weight (0, 0, -m g) at lever (0.5, 0, 0) is
    (0, +m g 0.5, 0), so tau_2 = +490.5 Nm about z_1, and nothing at the other joints (joint 1 is
    vertical, joints 3..6 are distal)."""
    robot = robot_with(tmp_path, one_mass(2, 100.0, [-500.0, 0.0, 0.0]))
    F = robot.frames(np.zeros((1, 6)))[0]
    np.testing.assert_allclose(F[1, :3, 2], [0, 1, 0], atol=1e-12)     # DH frame 1's z is base +y
    np.testing.assert_allclose((F[2] @ [-0.5, 0, 0, 1])[:3] - F[1, :3, 3], [0.5, 0, 0], atol=1e-12)
    tau = Statics(robot)(np.zeros(6)).total[0]
    np.testing.assert_allclose(tau, [0.0, 100 * 9.81 * 0.5, 0, 0, 0, 0], atol=1e-9)


def test_no_masses_no_payload_is_zero_and_the_balancer_takes_its_share(tmp_path, robot):
    bare = robot_with(tmp_path, None)
    q = random_q(bare, 30, 1)
    t = Statics(bare)(q)
    assert not t.total.any()
    share_robot = robot_with(tmp_path, {**read_extended(KR125)["inertial"],
                                        "balancer": {"joint": 3, "share": 0.25}})
    s = Statics(share_robot, 40.0, (0, 0, 100))(q)
    np.testing.assert_allclose(s.balancer[:, 2], -0.25 * s.arm[:, 2])
    assert not np.delete(s.balancer, 2, axis=1).any()
    np.testing.assert_allclose(s.total[:, 2], 0.75 * s.arm[:, 2] + s.payload[:, 2])
    # the shipped robot's balancer (joint 2) against the same arm without it
    shipped = Statics(robot, 40.0, (0, 0, 100))(q)
    np.testing.assert_allclose(shipped.arm, s.arm, rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(shipped.total[:, 1], (1 - robot.balancer.share) * s.arm[:, 1] + s.payload[:, 1])


def test_batched_equals_one_at_a_time_and_gravity_is_linear(robot):
    q = random_q(robot, 12, 2)
    st_ = Statics(robot, 55.0, (5, -5, 90))
    batch = st_(q).total
    single = np.array([st_(qk).total[0] for qk in q])
    np.testing.assert_array_equal(batch, single)
    up = Statics(robot, 55.0, (5, -5, 90), g_mps2=-G)(q).total      # a ceiling mount: all torques flip
    np.testing.assert_allclose(up, -batch, rtol=1e-12, atol=1e-9)
    assert robot.pin_model.nframes == Statics(robot).pm.nframes - 1   # the robot's own model is untouched


@pytest.mark.parametrize("kw, message", [
    ({"payload_kg": -1.0}, "payload mass = -1.0 kg must be a finite number >= 0"),
    ({"payload_kg": float("nan")}, "payload mass = nan kg"),
    ({"payload_cog_mm": (0, 0)}, "payload centre of gravity = .* mm must be three finite numbers"),
    ({"g_mps2": (0, 0, float("inf"))}, "gravity = .* must be three finite numbers"),
])
def test_bad_payload_is_refused(robot, kw, message):
    with pytest.raises(ValueError, match=message):
        Statics(robot, **kw)


def test_total_at_one_configuration_equals_the_batched_total(robot):
    q = random_q(robot, 10, 4)
    st_ = Statics(robot, 30.0, (0, 20, 100))
    np.testing.assert_allclose(np.array([st_.total_at(qk) for qk in q]), st_(q).total, rtol=1e-13, atol=1e-9)


# -- the preload's base columns: the first in key order of those that depend on each other ------------------

@settings(max_examples=60, deadline=None)
@given(st.integers(1, 6), st.integers(0, 2**31 - 1), st.data())
def test_independent_columns_keep_the_first_of_each_dependent_set(rank, seed, data):
    """Columns built as combinations of earlier ones (exact duplicates included, as mx2_kgm and m3_kg are for
    the KR 125's joint 2) are never kept; every kept column adds a direction; the kept set spans them all."""
    rng = np.random.default_rng(seed)
    n_cols = data.draw(st.integers(rank, 12))
    fresh = sorted(data.draw(st.lists(st.integers(1, n_cols - 1), unique=True, max_size=rank - 1))) if n_cols > 1 else []
    fresh = [0] + fresh
    Y = np.zeros((40, n_cols))
    for k in range(n_cols):
        if k in fresh:
            Y[:, k] = rng.normal(size=40)
        else:                                      # a combination of the columns before it (maybe one alone)
            w = rng.normal(size=k) * (rng.random(k) < 0.5)
            Y[:, k] = Y[:, :k] @ w
    kept = independent_columns(Y)
    assert kept == tuple(k for k in fresh if np.linalg.matrix_rank(Y[:, :k + 1]) > np.linalg.matrix_rank(Y[:, :k]))
    assert np.linalg.matrix_rank(Y[:, list(kept)]) == len(kept) == np.linalg.matrix_rank(Y)


def test_the_preload_keys_of_the_kr125_do_not_depend_on_rounding(robot):
    """Joint 2 feels link 3's mass m3 exactly as link 2's first moment m c_x (equal columns): the first key,
    mx2_kgm, is kept and m3_kg never, however the rounding falls (QR with pivoting kept m3_kg on one numpy
    and m5_kg on the next)."""
    from stiffness.kinematics.statics import base_columns, column_key

    keys = [column_key(k) for k in base_columns(robot, 2)]
    assert keys == [f"m{a}{link}_kgm" for link in range(2, 7) for a in "xy"]
    assert column_key(base_columns(robot, 3)[0]) == "mx3_kgm"
