"""nonlinear_stiffness: cubic c3 tau (tau/tau_ref)^2, or two-slope c_s tau_k tanh(tau/tau_k)."""

import numpy as np
import pytest
from effect_helpers import context, only

from hil.testing import model_with
from stiffness.effects.nonlinear_stiffness import NonlinearStiffness
from stiffness.errors import ConfigError


def test_cubic(robot):
    ctx = context(robot)
    e = NonlinearStiffness(2, "cubic", np.array([-1e-7]), reference_torque_Nm=1000.0)
    tau = ctx.frame_wrench[:, 1, 5]
    rz = only(e.twists(ctx, e.theta, ctx.frame_wrench), 1, 5)
    np.testing.assert_allclose(rz, -1e-7 * tau**3 / 1000.0**2)


def test_two_slope_is_softer_near_zero(robot):
    ctx = context(robot)
    cs, k = 2e-7, 300.0
    e = NonlinearStiffness(1, "two_slope", np.array([cs, k]))
    tau = ctx.frame_wrench[:, 0, 5]
    rz = only(e.twists(ctx, e.theta, ctx.frame_wrench), 0, 5)
    np.testing.assert_allclose(rz, cs * k * np.tanh(tau / k))
    small = np.abs(tau) < 0.05 * k
    if small.any():
        np.testing.assert_allclose(rz[small], cs * tau[small], rtol=2e-3)   # slope c_s at zero
    assert np.all(np.abs(rz) <= cs * k)                                      # saturates past the knee


def test_config(robot):
    m = model_with({"effect": "nonlinear_stiffness", "joint": 3, "form": "two_slope", "soft_rad_per_Nm": 1e-7,
                    "knee_Nm": 250})
    assert m.effects[-1].to_config()["knee_Nm"] == 250
    with pytest.raises(ConfigError, match="form = 'quartic' must be one of cubic, two_slope"):
        model_with({"effect": "nonlinear_stiffness", "joint": 3, "form": "quartic"})
