"""The structure's modes in the correction (stiffness/dynamics/structure.py).

Properties: a steady deflection passes unchanged (H(0) = 1), the rotation and what lies off every mode's
direction pass untouched; a step along a mode rings as a second-order system of that frequency and
damping does; the law cycle by cycle equals `Structure.respond` (one arithmetic); with added damping the
response to a slow load is the mode's to second order while its resonant gain is far lower; the config
refuses directions that are not orthogonal or zero.
"""

from __future__ import annotations

import numpy as np
import pytest
from pydantic import ValidationError
from scipy import signal

from stiffness.dynamics.base import DynamicsContext
from stiffness.dynamics.structure import Structure

MODES = [{"hz": 10.0, "damping": 0.03, "direction": [1, 0, 0]}, {"hz": 16.0, "damping": 0.03, "direction": [0, 1, 1]}]
CTX = DynamicsContext(period_s=0.001)


def part(added: float = 0.0, modes=MODES) -> Structure:
    return Structure(Structure.Config(modes=modes, added_damping=added))


def run(term, dX: np.ndarray) -> np.ndarray:
    out = np.array(dX, dtype=float)
    for row in out:
        term.law(term.state, term.params, row, 0.001)
    return out


def test_a_steady_deflection_and_what_the_modes_do_not_move_pass_unchanged():
    term = part().terms(CTX)[0]
    x = np.tile([1e-4, -2e-4, 3e-4, 1e-5, 2e-5, 3e-5], (30, 1))
    np.testing.assert_allclose(run(term, x), x, rtol=1e-9)
    term.reset()
    off = np.zeros((300, 6))
    off[5:, :] = [0.0, 1e-4, -1e-4, 1e-5, 1e-5, 1e-5]        # along (0, 1, -1): orthogonal to both modes
    np.testing.assert_allclose(run(term, off), off, atol=1e-15)


@pytest.mark.parametrize("k", [0, 1])
def test_a_step_along_a_mode_rings_at_its_frequency_and_damping(k):
    m = MODES[k]
    phi = np.array(m["direction"], dtype=float) / np.linalg.norm(m["direction"])
    x = np.zeros((600, 6))
    x[1:, :3] = 1e-3 * phi
    out = run(part().terms(CTX)[0], x)[:, :3] @ phi
    wn, z = 2 * np.pi * m["hz"], m["damping"]
    wd = wn * np.sqrt(1 - z * z)
    # the bilinear transform takes a step for a ramp over its first sample: the step half a sample late
    tau = np.maximum(np.arange(600) * 0.001 - 0.0005, 0.0)
    expected = 1.0 - np.exp(-z * wn * tau) * (np.cos(wd * tau) + z * wn / wd * np.sin(wd * tau))
    np.testing.assert_allclose(out[1:], 1e-3 * expected[1:], atol=0.01 * 1e-3)
    overshoot = out.max() / 1e-3 - 1.0
    assert overshoot == pytest.approx(np.exp(-z * np.pi / np.sqrt(1 - z * z)), rel=0.02)


def test_the_law_cycle_by_cycle_is_the_records_response():
    rng = np.random.default_rng(5)
    x = rng.normal(0, 1e-4, (800, 6)).cumsum(axis=0) * 0.05
    p = part(0.2)
    np.testing.assert_allclose(run(p.terms(CTX)[0], x)[:, :3], p.respond(x[:, :3], 0.001), rtol=1e-9, atol=1e-15)


def test_added_damping_keeps_the_slow_response_and_lowers_the_resonance():
    exact, robust = part(0.0, MODES[:1]), part(0.3, MODES[:1])
    gains = {}
    for name, p in (("exact", exact), ("robust", robust)):
        c = p.coefficients(0.001)[0]
        _, H = signal.freqz(c[:3], [1.0, c[3], c[4]], worN=[0.5, 1.0, 10.0], fs=1000.0)
        gains[name] = H
    # what the mode adds to a slow load (its lag and inertia) the robust filter adds too, to second order: the
    # difference, relative to it, is small and grows in proportion to the frequency (a third-order term)
    slow = np.abs(gains["robust"][:2] - gains["exact"][:2]) / np.abs(gains["exact"][:2] - 1.0)
    assert slow[0] < 0.04 and slow[1] / slow[0] == pytest.approx(2.0, rel=0.1)
    assert abs(gains["robust"][2]) < 0.15 * abs(gains["exact"][2])


@pytest.mark.parametrize("modes, match", [
    ([{"hz": 10, "damping": 0.03, "direction": [1, 0, 0]}, {"hz": 16, "damping": 0.03, "direction": [1, 1, 0]}],
     "orthogonal"),
    ([{"hz": 10, "damping": 0.03, "direction": [0, 0, 0]}], "must not be zero"),
])
def test_the_config_refuses_directions_that_are_no_modal_basis(modes, match):
    with pytest.raises(ValidationError, match=match):
        Structure.Config(modes=modes)
