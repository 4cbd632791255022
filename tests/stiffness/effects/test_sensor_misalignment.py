"""sensor_misalignment: W_true = blockdiag(R(phi), R(phi)) W_measured."""

import numpy as np
from effect_helpers import context

from hil.testing import model_with
from stiffness.effects.sensor_misalignment import SensorMisalignment
from stiffness.kinematics.spatial import exp_so3


def test_rotates_force_and_moment(robot):
    ctx = context(robot)
    phi = np.radians([1.0, -2.0, 0.5])
    w = SensorMisalignment(phi).wrench(ctx, phi, ctx.wrench_sensor)
    R = exp_so3(phi)
    np.testing.assert_allclose(w[:, :3], ctx.wrench_sensor[:, :3] @ R.T)
    np.testing.assert_allclose(np.linalg.norm(w[:, 3:], axis=1), np.linalg.norm(ctx.wrench_sensor[:, 3:], axis=1))
    np.testing.assert_allclose(SensorMisalignment().wrench(ctx, np.zeros(3), ctx.wrench_sensor), ctx.wrench_sensor)


def test_a_known_rotation_turns_the_axes_the_right_way(robot):
    """phi = +90 deg about z takes a measured force along x to the assumed sensor y axis."""
    ctx = context(robot, n=2)
    w = np.zeros((2, 6))
    w[:, 0], w[:, 4] = 100.0, 5.0            # fx and my
    out = SensorMisalignment().wrench(ctx, np.radians([0.0, 0.0, 90.0]), w)
    np.testing.assert_allclose(out[:, :3], [[0.0, 100.0, 0.0]] * 2, atol=1e-12)
    np.testing.assert_allclose(out[:, 3:], [[-5.0, 0.0, 0.0]] * 2, atol=1e-12)


def test_prediction_equals_the_model_fed_the_rotated_wrench(robot):
    from testlib.common import random_dataset
    data = random_dataset(robot, 20, 3)
    m = model_with({"effect": "sensor_misalignment", "rz_deg": 3.0}, base="kr125_6dof")
    plain = model_with(base="kr125_6dof")
    turned = data.subset(np.arange(len(data)))
    R = exp_so3(np.radians([0, 0, 3.0]))
    turned.wrench = np.c_[data.wrench[:, :3] @ R.T, data.wrench[:, 3:] @ R.T]
    np.testing.assert_allclose(m.predict(data), plain.predict(turned), atol=1e-12)
