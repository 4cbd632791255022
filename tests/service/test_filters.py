"""Low-pass and spike rejection: chunked equals all at once, equals scipy, unit DC gain."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import signal

from service.filters import SosLowPass, SpikeRejector


@pytest.mark.parametrize("kind, order", [("butterworth", 2), ("butterworth", 5), ("bessel", 3)])
def test_step_by_step_equals_scipy_sosfilt(kind, order):
    f = SosLowPass.design(kind, order, 80.0, 1000.0)
    x = np.random.default_rng(0).normal(size=(400, 6))
    y, _ = f.run(x)
    np.testing.assert_allclose(y, signal.sosfilt(f.sos, x, axis=0), atol=1e-12)


def test_chunked_equals_all_at_once():
    f = SosLowPass.design("butterworth", 4, 100.0, 1000.0)
    x = np.random.default_rng(1).normal(size=(300, 6))
    whole, z_whole = f.run(x)
    parts, z = [], None
    for chunk in np.array_split(x, [7, 8, 100, 251]):
        y, z = f.run(chunk, z)
        parts.append(y)
    np.testing.assert_allclose(np.concatenate(parts), whole, atol=1e-12)
    np.testing.assert_allclose(np.array(z), np.array(z_whole), atol=1e-12)


@pytest.mark.parametrize("kind", ["butterworth", "bessel"])
def test_dc_gain_is_one(kind):
    f = SosLowPass.design(kind, 3, 50.0, 1000.0)
    c = np.array([100.0, -50.0, 3.0, 1.0, -2.0, 0.5])
    y, _ = f.run(np.tile(c, (2000, 1)))
    np.testing.assert_allclose(y[-1], c, rtol=1e-9)


def test_steady_state_start_has_no_transient():
    f = SosLowPass.design("butterworth", 2, 100.0, 1000.0)
    c = [10.0, 20.0, 30.0, 1.0, 2.0, 3.0]
    y, _ = f.run(np.tile(c, (5, 1)), f.steady_state(c))
    np.testing.assert_allclose(y, np.tile(c, (5, 1)), rtol=1e-12)


def test_high_frequency_is_attenuated():
    f = SosLowPass.design("butterworth", 2, 100.0, 1000.0)
    t = np.arange(2000) / 1000.0
    x = np.sin(2 * np.pi * 400 * t)[:, None] * np.ones(6)
    y, _ = f.run(x)
    assert np.abs(y[1000:]).max() < 0.1 * np.abs(x).max()


def test_spike_is_held_and_a_real_step_is_accepted():
    s = SpikeRejector([100.0] * 3 + [10.0] * 3, max_held=2)
    base = [0.0] * 6
    assert s.update(base) == base
    spike = [500.0, 0, 0, 0, 0, 0]
    assert s.update(spike) == base                 # a single spike is replaced
    assert s.update(base) == base
    step = [300.0, 0, 0, 0, 0, 0]
    assert s.update(step) == base                  # held for max_held samples ...
    assert s.update(step) == base
    assert s.update(step) == step                  # ... then accepted as a load change
    assert s.rejected == 3
