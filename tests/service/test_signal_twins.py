"""The wrench's conditioning and the limiter are written twice: in Python (`service.filters.SpikeRejector`,
`SosLowPass`, `service.limits.CorrectionLimiter`, the reference) and compiled (`service.kernel.signal`'s
`condition` and `limit`, on the state arrays `service.kernel.compensator.CompiledSignal` lays out). Sample
by sample over wide inputs, spikes and load steps included, the two give the same outputs and state."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from service.filters import SosLowPass, SpikeRejector
from service.kernel.signal import (
    HAVE_LAST,
    HELD,
    LIMITER_STATE,
    MAX_DT,
    MAX_HELD,
    RAMP_S,
    RATE,
    REJECTED,
    SAFE_BEFORE,
    SPIKE_STATE,
    condition,
    limit,
)
from service.limits import CorrectionLimiter

finite = st.floats(-2000.0, 2000.0, allow_nan=False)
sample = st.lists(finite, min_size=6, max_size=6)


def close(a, b) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return bool(np.all(np.abs(a - b) <= 1e-12 * max(1.0, float(np.abs(b).max()))))


@settings(max_examples=60, deadline=None)
@given(st.lists(sample, min_size=1, max_size=40), st.sampled_from(["butterworth", "bessel", "none"]), st.integers(1, 6),
       st.floats(1.0, 400.0), st.integers(0, 4), st.floats(1.0, 500.0), st.floats(0.1, 50.0))
def test_the_compiled_conditioning_follows_the_python_stages(samples, kind, order, cutoff, max_held, step_n,
                                                            step_nm):
    spikes = SpikeRejector([step_n] * 3 + [step_nm] * 3, max_held)
    low = SosLowPass.design(kind, order, cutoff, 1000.0)
    sp = np.zeros(SPIKE_STATE)
    sp[MAX_HELD] = max_held
    last, y = np.zeros(6), np.zeros(6)
    coef = np.array(low._coef)
    z = np.zeros((len(coef), 2, 6))
    for x in samples:
        want = low.update(spikes.update(x))
        condition(np.array(x), sp, last, np.array(spikes.max_step), coef, z, y)
        assert close(y, want)
        assert close(z, low.state)
        assert (sp[HAVE_LAST], sp[HELD], sp[REJECTED]) == (1.0, spikes.held, spikes.rejected)
        assert close(last, spikes.last)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 0.02), st.lists(st.floats(-5.0, 5.0), min_size=6, max_size=6),
                          st.booleans()), min_size=1, max_size=40),
       st.floats(0.01, 3.0), st.floats(0.1, 100.0), st.floats(0.01, 2.0))
def test_the_compiled_limiter_follows_the_python_one(steps, max_deg, rate, ramp_s):
    py = CorrectionLimiter([max_deg] * 6, [rate] * 6, ramp_s, max_dt_s=0.01)
    lim = np.zeros(LIMITER_STATE)
    lim[:RATE], lim[RATE:RAMP_S] = py.max, py.rate
    lim[RAMP_S], lim[MAX_DT], lim[SAFE_BEFORE] = py.ramp_s, py.max_dt, float(py.safe)
    out, ramp_rate = np.zeros(6), np.zeros(6)
    for dt, target, safe in steps:
        want = py.update(dt, target, safe)
        limit(dt, np.array(target), safe, lim, out, ramp_rate)
        assert close(out, want)
        assert close(ramp_rate, py._ramp_rate) and lim[SAFE_BEFORE] == float(py.safe)
