"""The correction limiter: magnitude and rate limits, and the ramp to zero that never jumps."""

from __future__ import annotations

import numpy as np

from service.limits import CorrectionLimiter

DT = 1e-3


def test_magnitude_is_clipped():
    lim = CorrectionLimiter([0.1] * 6, [1e6] * 6, 0.2)
    out = lim.update(DT, [0.5, -0.5, 0.05, 0, 1, -1], safe=False)
    np.testing.assert_allclose(out, [0.1, -0.1, 0.05, 0, 0.1, -0.1])


def test_rate_is_limited_every_step():
    lim = CorrectionLimiter([1.0] * 6, [2.0] * 6, 0.2)
    prev = np.zeros(6)
    for k in range(300):
        target = np.sin(k / 10.0) * np.array([1, -1, 0.5, 0.2, 1, -0.7])
        out = np.array(lim.update(DT, target, safe=False))
        assert np.all(np.abs(out - prev) <= 2.0 * DT + 1e-12)
        prev = out


def test_safe_state_ramps_to_zero_in_ramp_time_without_jumps():
    lim = CorrectionLimiter([1.0] * 6, [1e6] * 6, ramp_s=0.2)
    start = np.array(lim.update(DT, [0.5, -0.4, 0.3, 0.2, -0.1, 0.05], safe=False))
    steps = [start]
    for _ in range(400):
        steps.append(np.array(lim.update(DT, [0.9] * 6, safe=True)))
    steps = np.array(steps)
    jumps = np.abs(np.diff(steps, axis=0))
    assert np.all(jumps <= np.abs(start) / 0.2 * DT + 1e-12)
    assert np.all(steps[int(0.2 / DT) + 1] == 0.0)
    assert not lim.ramping


def test_resume_after_safe_is_rate_limited():
    lim = CorrectionLimiter([1.0] * 6, [5.0] * 6, 0.2)
    lim.update(DT, [0.0] * 6, safe=True)
    out = lim.update(DT, [0.5] * 6, safe=False)
    assert np.allclose(out, 5.0 * DT)


def test_a_stall_moves_the_output_by_at_most_two_periods_of_rate():
    lim = CorrectionLimiter([1.0] * 6, [2.0] * 6, 0.2, max_dt_s=2 * DT)
    lim.update(DT, [0.0] * 6, safe=False)
    out = np.array(lim.update(0.5, [1.0] * 6, safe=False))          # the cycle stalled for 500 ms
    np.testing.assert_allclose(out, 2.0 * 2 * DT)
    start = out.copy()
    out = np.array(lim.update(0.5, [0.0] * 6, safe=True))           # and on the ramp to zero
    assert np.all(start - out <= start / 0.2 * 2 * DT + 1e-12)
