"""backlash: delta_rz,i = (b/2) tanh(tau_i / tau_w) at DH frame i-1."""

import numpy as np
import pytest
from effect_helpers import context, only

from hil.testing import model_with
from stiffness.effects.backlash import Backlash
from stiffness.errors import ConfigError


def test_equation_and_limits(robot):
    ctx = context(robot)
    b, w = np.radians(0.02), 5.0
    e = Backlash(3, b, w)
    tau = ctx.frame_wrench[:, 2, 5]
    rz = only(e.twists(ctx, e.theta, ctx.frame_wrench), 2, 5)
    np.testing.assert_allclose(rz, 0.5 * b * np.tanh(tau / w))
    assert np.all(np.abs(rz) <= b / 2)                       # bounded by half the play
    big = np.abs(tau) > 10 * w
    np.testing.assert_allclose(np.abs(rz[big]), b / 2, rtol=1e-6)   # saturated away from zero
    np.testing.assert_allclose(e.twists(ctx, e.theta, -ctx.frame_wrench), -e.twists(ctx, e.theta, ctx.frame_wrench))


def test_moves_only_bodies_beyond_the_joint(robot):
    from testlib.common import random_dataset
    data = random_dataset(robot, 20, 1)
    m = model_with({"effect": "backlash", "joint": 4, "lost_motion_deg": 0.05, "width_Nm": 1.0})
    theta = m.theta.copy()
    theta[:6] = 0.0                                           # springs off: the backlash alone
    d = m.predict(data, theta)
    assert np.abs(d[data.body < 3]).max() == 0.0
    assert np.abs(d[data.body >= 3]).max() > 0.0


def test_yaml_round_trip_and_errors(robot):
    m = model_with({"effect": "backlash", "joint": 2, "lost_motion_deg": 0.01, "width_Nm": 3})
    e = m.effects[-1]
    assert e.to_config() == {"effect": "backlash", "joint": 2, "lost_motion_deg": 0.01, "width_Nm": 3.0}
    with pytest.raises(ConfigError, match=r"width_Nm = -1 is outside \[0.1, 10000\] Nm"):
        model_with({"effect": "backlash", "joint": 2, "width_Nm": -1})
    with pytest.raises(ConfigError, match="joint is missing"):
        model_with({"effect": "backlash", "lost_motion_deg": 0.01})
