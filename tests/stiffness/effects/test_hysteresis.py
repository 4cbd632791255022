"""hysteresis: delta_rz,i = h z_i, z_i the loading state, dz/dtau = (sgn(dtau) - z) / tau_t (Dahl) beyond the
breakaway, the torque the joint follows (a low-pass at bandwidth_hz).

Properties: the instant switch (tau_t = 0) is the direction the torque last moved; a monotone move
taken in many small steps gives the state one step gives (the law is integrated exactly); z stays in
[-1, 1]; chatter below the breakaway leaves z alone; z is continuous in the torque (no jump where a
reversal passes the breakaway); a small transition tends to the instant switch; a ripple faster than the
bandwidth does not move z, a slow move does; the state carries across the load sequences of one
configuration and restarts at the next.
"""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stiffness.data.campaign import Context
from stiffness.data.measurements import Dataset
from stiffness.effects.hysteresis import Hysteresis, LoadingState, loading_state
from stiffness.errors import ConfigError

torques = st.lists(st.floats(-2000, 2000, allow_nan=False), min_size=1, max_size=60)


def ramp_context(robot, levels, repeats=2, configs=("C",)):
    """Each configuration ramped through ``levels`` (N along the sensor's x axis), in time order."""
    f = np.tile(np.repeat(levels, repeats).astype(float), len(configs))
    n = len(f)
    W = np.zeros((n, 6))
    W[:, 0] = f                                       # sensor x force
    W[:, 0] += np.tile([0.0, 0.3], n // 2 + 1)[:n]    # repeated readings differ by noise
    labels = np.repeat(configs, n // len(configs))
    data = Dataset(np.arange(n, dtype=float), labels, np.tile([10, -75, 90, 0, 75, 0], (n, 1)),
                   W, np.full(n, 6), np.zeros((n, 6)))
    return Context(robot, data)


def run(tau, threshold=2.0, transition=0.0):
    s = LoadingState(threshold, transition)
    return np.array([s.update(float(t)) for t in tau])


def test_instant_switch_is_the_direction_the_torque_last_moved(robot):
    levels = [0, 300, 600, 300, 0, -300, -600, -300, 0]
    ctx = ramp_context(robot, levels)
    j = int(np.argmax(np.abs(ctx.frame_wrench[:, :6, 5]).max(axis=0)))   # the joint this load turns most
    tau = ctx.frame_wrench[:, j, 5]
    order = np.argsort(ctx.time)
    z = loading_state(ctx, tau, 2.0, 0.0)[order]
    sign = np.sign(tau[order][2] - tau[order][0])
    expected = np.repeat([0, 1, 1, -1, -1, -1, -1, 1, 1], 2) * sign
    np.testing.assert_array_equal(z, expected)


@settings(max_examples=200, deadline=None)
@given(start=st.floats(-1000, 1000), moves=st.lists(st.floats(3.0, 400.0), min_size=1, max_size=5),
       splits=st.integers(2, 40), transition=st.floats(0.5, 500.0), z0_up=st.booleans())
def test_a_monotone_move_in_small_steps_equals_one_step(start, moves, splits, transition, z0_up):
    """Exact integration: z after a monotone stretch depends on where it ends, not on the sampling."""
    sign = 1.0 if z0_up else -1.0
    coarse = [start] + list(start + sign * np.cumsum(moves))
    fine = [start] + list(np.linspace(start, coarse[-1], splits + 1)[1:])
    a, b = run(coarse, 2.0, transition), run(fine, 2.0, transition)
    assert b[-1] == pytest.approx(a[-1], abs=1e-12)
    slip = max(abs(coarse[-1] - start) - 2.0, 0.0)          # the move beyond the breakaway slips
    assert b[-1] == pytest.approx(sign * (1 - np.exp(-slip / transition)), abs=1e-12)


@settings(max_examples=200, deadline=None)
@given(tau=torques, threshold=st.floats(0.0, 50.0), transition=st.floats(0.0, 1000.0))
def test_state_stays_between_the_branches(tau, threshold, transition):
    z = run(tau, threshold, transition)
    assert np.all(np.abs(z) <= 1.0) and z[0] == 0.0


@settings(max_examples=100, deadline=None)
@given(base=st.floats(-1000, 1000), noise=st.lists(st.floats(-0.99, 0.99), min_size=1, max_size=50),
       transition=st.floats(0.0, 200.0))
def test_chatter_below_the_threshold_leaves_a_settled_state(base, noise, transition):
    """After a rise to ``base`` (settled on the upper branch), noise whose peak-to-peak is below the
    threshold (2 Nm) never takes z off the upper branch; 2.5 Nm back does."""
    s = LoadingState(2.0, transition)
    for t in (base - 5000.0, base):
        s.update(t)
    z0 = s.z
    for n in noise:
        assert s.update(base + n) >= z0 - 1e-12
    assert s.update(s.ref - 2.5) < z0


@settings(max_examples=100, deadline=None)
@given(tau=torques)
def test_a_small_transition_tends_to_the_instant_switch(tau):
    tau = np.round(np.asarray(tau))             # moves are >= 1 Nm or 0: e^(-1/1e-3) underflows
    np.testing.assert_allclose(run(tau, 0.5, 1e-3), run(tau, 0.5, 0.0), atol=1e-12)


@settings(max_examples=200, deadline=None)
@given(tau=torques, threshold=st.floats(0.5, 50.0), transition=st.floats(1.0, 500.0),
       k=st.integers(0, 59), eps=st.floats(1e-7, 1e-4))
def test_the_state_is_continuous_in_the_torque(tau, threshold, transition, k, eps):
    """A torque off by eps at one sample moves z by at most about eps / tau_t then and after (before the
    breakaway, z sticks; beyond it, it slips from where it stood): a reading that just passes the breakaway
    is no full step in either direction."""
    if k >= len(tau):
        return
    nudged = list(tau)
    nudged[k] += eps
    a, b = run(tau, threshold, transition), run(nudged, threshold, transition)
    assert np.abs(a - b).max() <= 4 * eps / transition + 1e-9


def test_a_ripple_faster_than_the_bandwidth_leaves_the_state_a_slow_move_does_not():
    """On a 1 ms cycle: a +-30 Nm ripple at 400 Hz (three times the breakaway) on a steady torque leaves z on
    its branch, where the torque as it is would take it most of the way across; a slow move back of 100 Nm
    takes it across (the joint follows the torque below 10 Hz)."""
    t = np.arange(0.0, 0.5, 0.001)
    ripple = 500.0 + 30.0 * np.sin(2 * np.pi * 400.0 * t + 0.3)
    smooth, raw = LoadingState(10.0, 20.0, 10.0), LoadingState(10.0, 20.0, 0.0)
    for s in (smooth, raw):
        s.update(0.0)
        s.update(500.0, 1.0)                   # settled on the upper branch
    z_smooth = [smooth.update(x, 0.001) for x in ripple]
    z_raw = [raw.update(x, 0.001) for x in ripple]
    assert min(z_smooth) > 0.99 and min(z_raw) < 0.0
    for x in np.linspace(500.0, 400.0, 200):
        smooth.update(x, 0.001)
    for _ in range(300):
        smooth.update(400.0, 0.001)
    assert smooth.z < -0.9


def test_state_carries_across_sequences_and_restarts_per_configuration(robot):
    levels = [0, 600, 0, -600, 0, 300]               # six per configuration: the same noise in each
    ctx = ramp_context(robot, levels, repeats=1, configs=("A", "B"))
    tau = ctx.frame_wrench[:, 1, 5]
    z = loading_state(ctx, tau, 2.0, 200.0)
    order = np.argsort(ctx.time)
    za, zb = z[order][:6], z[order][6:]
    np.testing.assert_array_equal(za, zb)          # B starts again at 0: the same torques, the same z
    assert za[0] == 0.0
    seq = run(tau[order][:6], 2.0, 200.0)
    np.testing.assert_allclose(za, seq)            # within A: one state through the whole sequence
    # readings 2 and 4 are both back at 0 N, coming from opposite sides: opposite branches, and
    # neither reached (the 200 Nm transition is smooth), so each carries the state before it
    assert np.sign(za[2]) == -np.sign(za[4]) != 0 and np.abs(za[1:]).max() < 1.0


def test_twist_is_offset_times_state(robot):
    ctx = ramp_context(robot, [0, 500, 0, -500, 0])
    h = np.radians(-0.004)
    e = Hysteresis(2, h, transition_Nm=80.0)
    tw = e.twists(ctx, e.theta, ctx.frame_wrench)
    z = loading_state(ctx, ctx.frame_wrench[:, 1, 5], e.threshold_Nm, 80.0)
    assert len(np.unique(np.round(z, 6))) > 3                    # smooth: more than three values
    np.testing.assert_allclose(tw[:, 1, 5], h * z)
    assert np.abs(np.delete(tw.reshape(len(tw), -1), 6 + 5, axis=1)).max() == 0.0


def test_yaml_round_trip_and_the_old_key(robot):
    e = Hysteresis.from_config({"effect": "hysteresis", "joint": 3, "offset_deg": -0.004, "transition_Nm": 40,
                                "threshold_Nm": 1.5}, robot, "m.yaml: effects[0]")
    again = Hysteresis.from_config(e.to_config(), robot, "again")
    assert again.to_config() == e.to_config() and again.transition(again.theta) == 40.0
    with pytest.raises(ConfigError, match=r"m.yaml: effects\[0\]: threshold_fraction .* threshold_Nm"):
        Hysteresis.from_config({"effect": "hysteresis", "joint": 3, "threshold_fraction": 0.02}, robot,
                               "m.yaml: effects[0]")
    with pytest.raises(ConfigError, match=r"transition_Nm = -1 is outside"):
        Hysteresis.from_config({"effect": "hysteresis", "joint": 3, "transition_Nm": -1}, robot, "m.yaml")


def test_the_first_breakaway_is_measured_from_the_range_since_the_start():
    """Before the first move the contacts stick while the torque stays within the breakaway of every torque
    since the start; the first move beyond it turns at the lowest (highest) torque so far. CI's example:
    from 0.5 down to 0 (exactly the breakaway, a stick) and up to 1 slips by 0.5 from 0, as it does when
    the start is 6e-5 higher and the move down already broke away."""
    a, b = run([0.5, 0.0, 1.0], 0.5, 1.0), run([0.5 + 6.1e-5, 0.0, 1.0], 0.5, 1.0)
    assert a[1] == 0.0 and a[2] == pytest.approx(1.0 - np.exp(-0.5), abs=1e-12)
    assert np.abs(a - b).max() <= 4 * 6.1e-5
    down = run([0.0, 0.4, -0.3], 0.5, 0.0)             # 0.7 below the highest (0.4): the instant switch
    np.testing.assert_array_equal(down, [0.0, 0.0, -1.0])
