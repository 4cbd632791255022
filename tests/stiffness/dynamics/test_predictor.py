"""The wrench predictor: P(s) = 1 + h s w_d^2 / (s + w_d)^2 per channel (stiffness/dynamics/predictor.py).

Properties: a steady wrench passes unchanged from the first cycle (P(0) = 1, steady-state start); a ramp
comes out h ahead once settled, for any horizon and bandwidth; a negative horizon delays; the law run cycle
by cycle is scipy's filter of the same biquad (chunks equal the whole); the gain never exceeds 1 + h w_d / 2.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import signal

from stiffness.dynamics.base import DynamicsContext
from stiffness.dynamics.predictor import Predictor

CTX = DynamicsContext(period_s=0.001, delay_s=0.012, lag_s=0.004)


def run(term, w: np.ndarray) -> np.ndarray:
    out = np.array(w, dtype=float)
    for row in out:
        term.law(term.state, term.params, row, 0.001)
    return out


@settings(max_examples=30, deadline=None)
@given(w0=st.lists(st.floats(-2000, 2000), min_size=6, max_size=6), h=st.floats(-10.0, 50.0))
def test_a_steady_wrench_passes_unchanged_from_the_first_cycle(w0, h):
    term = Predictor(Predictor.Config(horizon_ms=h)).terms(CTX)[0]
    out = run(term, np.tile(w0, (50, 1)))
    np.testing.assert_allclose(out, np.tile(w0, (50, 1)), atol=1e-9 * (1 + np.abs(w0).max()))


@settings(max_examples=30, deadline=None)
@given(h=st.floats(1.0, 30.0), hz=st.floats(20.0, 100.0), slope=st.floats(-500.0, 500.0))
def test_a_ramp_comes_out_h_ahead(h, hz, slope):
    term = Predictor(Predictor.Config(horizon_ms=h, bandwidth_hz=hz)).terms(CTX)[0]
    t = np.arange(2000) * 0.001
    w = np.outer(slope * t, np.ones(6))
    out = run(term, w)
    np.testing.assert_allclose(out[-1], slope * (t[-1] + h / 1000.0), atol=1e-6 * (1 + abs(slope)))


def test_the_default_horizon_is_the_delay_less_the_lag_and_a_negative_one_delays():
    p = Predictor(Predictor.Config())
    assert p.horizon_s(CTX) == pytest.approx(0.008)
    term = Predictor(Predictor.Config(horizon_ms=-5.0)).terms(CTX)[0]
    t = np.arange(3000) * 0.001
    out = run(term, np.outer(100.0 * t, np.ones(6)))
    assert out[-1, 0] == pytest.approx(100.0 * (t[-1] - 0.005), abs=1e-6)


def test_the_law_is_the_biquad_and_chunks_equal_the_whole():
    rng = np.random.default_rng(3)
    w = rng.normal(0.0, 50.0, (500, 6)).cumsum(axis=0)
    part = Predictor(Predictor.Config(horizon_ms=8.0))
    term = part.terms(CTX)[0]
    c = part.coefficients(CTX)
    b, a = c[:3], np.array([1.0, c[3], c[4]])
    expected = signal.lfilter(b, a, w, axis=0, zi=signal.lfilter_zi(b, a)[:, None] * w[:1])[0]
    whole = run(term, w)
    np.testing.assert_allclose(whole, expected, rtol=1e-9, atol=1e-9)
    term.reset()
    chunks = np.vstack([run(term, w[:137]), run(term, w[137:])])
    np.testing.assert_array_equal(chunks, whole)


@pytest.mark.parametrize("h, hz", [(8.0, 40.0), (20.0, 40.0), (8.0, 100.0)])
def test_the_gain_stays_below_its_bound(h, hz):
    c = Predictor(Predictor.Config(horizon_ms=h, bandwidth_hz=hz)).coefficients(CTX)
    _, H = signal.freqz(c[:3], [1.0, c[3], c[4]], worN=4096)
    assert np.abs(H).max() <= 1.0 + (h / 1000.0) * 2 * np.pi * hz / 2 + 1e-3
