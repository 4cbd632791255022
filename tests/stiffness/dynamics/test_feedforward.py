"""The feedforward from the process plan (stiffness/dynamics/feedforward.py).

Properties: with a plan that is right (the measured wrench is the planned one, late by the horizon, through
the predictor), the wrench that leaves the term is the plan's at tau*, on time, at an entry too; outside a
program it adds nothing; the PLC's engagement written ahead is read back at the times it stands for; a plan
file's errors name the file and the line.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stiffness.dynamics.base import DynamicsContext
from stiffness.dynamics.feedforward import Feedforward, Plan, read_plan
from stiffness.dynamics.predictor import Predictor
from stiffness.errors import DataError

P_TCP = [1.6, 0.1, 0.9]
T = np.arange(0.0, 1.0, 0.001)


def plan() -> Plan:
    e = np.clip((T - 0.3) / 0.05, 0.0, 1.0)                     # an entry over 50 ms at 0.3 s
    return Plan(T, e, np.tile([0.0, 400.0, 150.0], (len(T), 1)))


def ctx_with_predictor(h_ms: float) -> DynamicsContext:
    ctx = DynamicsContext(period_s=0.001, delay_s=0.010, lag_s=0.002)
    pred = Predictor(Predictor.Config(horizon_ms=h_ms))
    return pred.context(ctx), pred


@pytest.mark.parametrize("h_ms", [0.0, 8.0])
def test_a_right_plan_puts_the_planned_wrench_on_time(h_ms):
    """The measured wrench is W_p(tau - h + lead) (what the measurement shows), predicted by P; the term adds
    the plan's change, and what leaves is W_p(tau + lead) to rounding, through the entry."""
    ctx, pred = ctx_with_predictor(h_ms)
    ff = Feedforward(Feedforward.Config(file="plan.csv", output_delay_ms=2.0), plan())
    p_term, f_term = pred.terms(ctx)[0], ff.terms(ctx)[0]
    lead, h = ff.lead_s, h_ms / 1000.0
    worst = 0.0
    for k, t in enumerate(T[:-60]):
        ff.feed(t, t, P_TCP)                      # the PLC's program time is the scenario's
        w = np.array(ff.plan.wrench(t + lead - h, P_TCP))
        p_term.law(p_term.state, p_term.params, w, 0.001)
        f_term.law(f_term.state, f_term.params, w, 0.001)
        worst = max(worst, np.abs(w - ff.plan.wrench(t + lead, P_TCP)).max())
    assert worst < 1e-6


def test_outside_a_program_it_adds_nothing():
    ctx, _ = ctx_with_predictor(5.0)
    ff = Feedforward(Feedforward.Config(file="plan.csv"), plan())
    term = ff.terms(ctx)[0]
    w0 = np.array([10.0, -20.0, 30.0, 1.0, 2.0, 3.0])
    for t in T[:200]:
        ff.feed(t, -1.0, P_TCP)
        w = w0.copy()
        term.law(term.state, term.params, w, 0.001)
        np.testing.assert_allclose(w, w0, atol=1e-12)


def test_the_plcs_engagement_ahead_is_read_at_the_time_it_stands_for():
    ctx, _ = ctx_with_predictor(0.0)
    cfg = Feedforward.Config(source="plc", force_N=[0.0, 400.0, 0.0], lookahead_ms=40.0, output_delay_ms=6.0)
    ff = Feedforward(cfg)
    term = ff.terms(ctx)[0]
    e = plan().e
    for k, t in enumerate(T[:600]):
        ff.feed(t, float(np.interp(t + 0.040, T, e)), P_TCP)
    # now (t = 0.599): tau* = t + lead, with lead = output_delay - lag = 4 ms
    assert term.state[1] == pytest.approx(400.0 * np.interp(T[599] + ff.lead_s, T, e), abs=1e-9)
    with pytest.raises(ValueError, match="lookahead_ms = 1 cannot reach"):
        Feedforward(Feedforward.Config(source="plc", force_N=[0, 1, 0], lookahead_ms=1.0, output_delay_ms=6.0)).terms(ctx)


@pytest.mark.parametrize("text, match", [
    ("t_s,engagement\n0,0\n0.1,1.5\n0.2,12\n", r"plan.csv: engagement = 12 at t_s = 0.2 is outside \[0, 10\]"),
    ("t_s,engagement\n0,0\n0.1,x\n", r"plan.csv: 1 problem"),
    ("t_s,engagement\n0,0\n0,1\n", r"plan.csv: 1 problem"),
    ("t_s,load\n0,0\n", r"plan.csv: line 1: missing column\(s\) engagement"),
    ("t_s,engagement,fx_N\n0,0,1\n1,1,1\n", r"give all of fx_N, fy_N, fz_N or none"),
    ("t_s,engagement\n0,0\n1,1\n", r"has no force columns .*force_N is not set"),
])
def test_a_bad_plan_file_is_named_with_its_line(tmp_path, text, match):
    path = tmp_path / "plan.csv"
    path.write_text(text)
    with pytest.raises(DataError, match=match) as e:
        read_plan(path)
    if "problem" in match:
        assert any("line 3" in p for p in e.value.problems), e.value.problems


@given(st.lists(st.floats(0.0, 2.0), min_size=1, max_size=40), st.lists(st.floats(-5.0, 50.0), min_size=1, max_size=30),
       st.integers(0, 2**32 - 1))
@settings(max_examples=60, deadline=None)
def test_the_engagement_is_the_line_between_the_rows(engagements, taus, seed):
    """Plan.engagement (read twice per cycle, without NumPy) is np.interp of the plan, held beyond its ends."""
    rng = np.random.default_rng(seed)
    t = np.cumsum(rng.uniform(0.001, 2.0, len(engagements)))
    e = np.array(engagements)
    p = Plan(np.column_stack([t, e])[:, 0], e, np.tile([1.0, 2.0, 3.0], (len(t), 1)))   # a strided column too
    for tau in [*taus, *t]:
        assert p.engagement(tau) == pytest.approx(float(np.interp(tau, t, e)), abs=1e-12)
