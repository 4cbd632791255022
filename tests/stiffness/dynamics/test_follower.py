"""The modes followed in the cut (`stiffness.dynamics.follower`), on a simulated arm: one mode along x carrying a
static deflection that enters a cut (a 50 ms ramp at 0.5 s) and leaves it, seen by the box (its 62.5 Hz
low-pass, 3 ms of age), the structure and the observer running their laws as the cycle does:

* with the model's frequency 10-25 % off either way, for arms from 7 to 16 Hz, the follower hands the
  structure and the observer the arm's frequency within 1.5 % within 0.4 s of the entry, and changes nothing
  before it (hypothesis);
* with the frequency right, it changes nothing;
* 10 s of the box's noise at rest, no cut: nothing changes;
* the frequency it hands over is what the running terms then hold: their parameters are the parts' own at it;
* a `follow_range` whose candidates the band cannot hold is refused, naming both.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydantic import ValidationError
from scipy import signal

from hil.structure import oscillate
from stiffness.dynamics.base import DynamicsContext
from stiffness.dynamics.observer import Observer
from stiffness.dynamics.structure import Structure

pytestmark = pytest.mark.slow

DT = 0.001
ENTRY_S = 0.5


def follow(f_true: float, f_model: float, seconds: float = 2.0, cut: bool = True, seed: int = 1):
    """[(t, hz)] the follower's changes, and the structure's and the observer's terms at the end, and the parts."""
    t = np.arange(0.0, seconds, DT)
    level = 60e-6 if cut else 0.0
    xs = np.interp(t, [0, ENTRY_S, ENTRY_S + 0.05, seconds - 0.3, seconds - 0.2, seconds], [0, 0, level, level, 0, 0])
    xs = signal.lfilter(*signal.butter(2, 40, fs=1 / DT), xs)
    d = oscillate(xs[:, None], np.full((len(t), 1), 2 * np.pi * f_true), np.array([0.03]), DT)[:, 0]
    acc = signal.sosfilt(signal.butter(2, 62.5, fs=1 / DT, output="sos"), np.gradient(np.gradient(d, DT), DT))
    acc = np.concatenate([np.zeros(3), acc[:-3]]) + np.random.default_rng(seed).normal(0.0, 9.80665e-3, len(t))
    modes = [{"hz": f_model, "damping": 0.03, "direction": [1, 0, 0]}]
    structure = Structure(Structure.Config(modes=modes))
    observer = Observer(Observer.Config(modes=modes, horizon_ms=5.0, follow=True))
    ts, to = structure.terms(DynamicsContext(DT))[0], observer.terms(DynamicsContext(DT))[0]
    changes = []

    def apply(hz):
        for part, term in ((structure, ts), (observer, to)):
            p = part.with_frequencies(hz).params(DT)
            term.params[:len(p)] = p
        changes.append((k * DT, hz[0]))

    follower = observer.follower(DT, apply)
    ahead = np.concatenate([xs[2:], np.full(2, xs[-1])])      # the predictor's: the static deflection 2 ms ahead
    for k in range(len(t)):
        observer.feed_motion([acc[k], 0.0, 0.0], True, [1.8, 0.0, 0.8])
        dX = np.zeros(6)
        dX[0] = ahead[k]
        ts.law(ts.state, ts.params, dX, DT)
        to.law(to.state, to.params, dX, DT)
        if Observer.settled(to):
            follower.step(Structure.inputs(ts), Observer.measured(to))
        else:
            follower.restart()
    return changes, (ts, to), (structure, observer)


@settings(max_examples=15, deadline=None)
@given(f_true=st.floats(7.0, 16.0), error=st.floats(0.1, 0.25), sign=st.sampled_from([-1.0, 1.0]))
def test_a_mode_that_is_off_is_followed_to_the_arms_frequency_after_the_entry(f_true, error, sign):
    changes, _, _ = follow(f_true, f_true * (1.0 + sign * error))
    assert changes, "no change"
    assert all(t > ENTRY_S for t, _ in changes)
    t_first, hz = changes[0]
    assert t_first < ENTRY_S + 0.4 and abs(hz / f_true - 1.0) < 0.015, changes
    assert all(abs(f / f_true - 1.0) < 0.015 for _, f in changes), changes


def test_a_mode_that_is_right_stays():
    changes, _, _ = follow(10.0, 10.0)
    assert changes == []


def test_ten_seconds_of_the_boxs_noise_at_rest_change_nothing():
    changes, _, _ = follow(10.0, 12.0, seconds=10.0, cut=False, seed=2)
    assert changes == []


def test_the_running_terms_hold_the_parts_own_parameters_at_the_followed_frequency():
    changes, (ts, to), (structure, observer) = follow(10.0, 12.0)
    hz = [changes[-1][1]]
    assert np.array_equal(ts.params, structure.with_frequencies(hz).params(DT))
    assert np.array_equal(to.params, observer.with_frequencies(hz).params(DT))
    assert not np.array_equal(ts.params, structure.params(DT))


def test_a_range_the_band_cannot_hold_is_refused_naming_both():
    """The candidates run from f / (1 + range) to f (1 + range): 3.4 Hz / 1.4 lies below the band's 2.5 Hz."""
    mode = {"hz": 3.4, "damping": 0.03, "direction": [1, 0, 0]}
    Observer.Config(modes=[mode])                                   # without follow the band holds the mode
    Observer.Config(modes=[{**mode, "hz": 3.6}], follow=True)      # 3.6 / 1.4 = 2.57 Hz
    with pytest.raises(ValidationError, match="band_hz .* follow_range 0.4"):
        Observer.Config(modes=[mode], follow=True)
