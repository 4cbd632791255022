"""hysteresis: delta_rz,i = h s_i(t), s_i the direction the torque last moved (time order)."""

import numpy as np

from stiffness.context import Context
from stiffness.effects.hysteresis import Hysteresis, loading_direction
from stiffness.measurements import Dataset


def ramp_context(robot, levels, repeats=2):
    """One configuration, the load ramped through ``levels`` (N along the sensor's x axis)."""
    f = np.repeat(levels, repeats).astype(float)
    n = len(f)
    W = np.zeros((n, 6))
    W[:, 0] = f                                       # sensor x force
    W[:, 0] += np.tile([0.0, 0.3], n // 2 + 1)[:n]    # repeated readings differ by noise
    data = Dataset(np.arange(n, dtype=float), np.array(["C"] * n), np.tile([10, -75, 90, 0, 75, 0], (n, 1)),
                   W, np.full(n, 6), np.zeros((n, 6)))
    return Context(robot, data)


def test_direction_follows_the_ramp(robot):
    levels = [0, 300, 600, 300, 0, -300, -600, -300, 0]
    ctx = ramp_context(robot, levels)
    j = int(np.argmax(np.abs(ctx.frame_wrench[:, :6, 5]).max(axis=0)))   # the joint this load turns most
    tau = ctx.frame_wrench[:, j, 5]
    order = np.argsort(ctx.time)
    s = loading_direction(ctx, tau, 0.02)[order]
    sign = np.sign(tau[order][2] - tau[order][0])     # which way joint 1's torque goes with +F
    expected = np.repeat([0, 1, 1, -1, -1, -1, -1, 1, 1], 2) * sign
    np.testing.assert_array_equal(s, expected)


def test_twist_is_offset_times_direction(robot):
    ctx = ramp_context(robot, [0, 500, 0, -500, 0])
    h = np.radians(-0.004)
    e = Hysteresis(2, h)
    tw = e.twists(ctx, e.theta, ctx.frame_wrench)
    s = loading_direction(ctx, ctx.frame_wrench[:, 1, 5], 0.02)
    assert set(np.unique(s)) == {-1.0, 0.0, 1.0}
    np.testing.assert_allclose(tw[:, 1, 5], h * s)
    assert np.abs(np.delete(tw.reshape(len(tw), -1), 6 + 5, axis=1)).max() == 0.0
