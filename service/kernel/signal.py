"""The wrench's conditioning in the compiled cycle: spike rejection and the low-pass (numba, no allocation).

The same equations as `service.filters.SpikeRejector` and `service.filters.SosLowPass` (direct form II
transposed per section, as scipy.signal.sosfilt), on the state arrays those objects own, so the Python
and the compiled path can take turns on one filter.
"""

from __future__ import annotations

from numba import njit

# the spike rejector's state `sp`, by place (numba takes these module constants as literals)
HAVE_LAST, HELD, MAX_HELD, REJECTED = 0, 1, 2, 3
SPIKE_STATE = 4
# the limiter's `lim`: the six maxima from 0, the six rates from RATE, then three scalars
RATE, RAMP_S, MAX_DT, SAFE_BEFORE = 6, 12, 13, 14
LIMITER_STATE = 15


@njit(cache=True)
def condition(x, sp, last, max_step, coef, z, y):
    """Spikes, then the low-pass, for one sample x (6,); y (6,) the filtered sample.

    sp: [have_last, held, max_held, rejected]; last (6,) the last accepted value; coef (S, 5) b0 b1 b2 a1
    a2 per section; z (S, 2, 6) the sections' state."""
    if sp[HAVE_LAST] == 0.0:
        for i in range(6):
            last[i] = x[i]
        sp[HAVE_LAST] = 1.0
    else:
        jump = False
        for i in range(6):
            if abs(x[i] - last[i]) > max_step[i]:
                jump = True
        if sp[HELD] < sp[MAX_HELD] and jump:
            sp[HELD] += 1.0
            sp[REJECTED] += 1.0
        else:
            sp[HELD] = 0.0
            for i in range(6):
                last[i] = x[i]
    for i in range(6):
        y[i] = last[i]
    for s in range(coef.shape[0]):
        b0, b1, b2, a1, a2 = coef[s, 0], coef[s, 1], coef[s, 2], coef[s, 3], coef[s, 4]
        for i in range(6):
            xi = y[i]
            yi = b0 * xi + z[s, 0, i]
            z[s, 0, i] = b1 * xi - a1 * yi + z[s, 1, i]
            z[s, 1, i] = b2 * xi - a2 * yi
            y[i] = yi


@njit(cache=True)
def limit(dt, target, safe, lim, out, ramp_rate):
    """The limiter (`service.filters`' neighbour `service.limits.CorrectionLimiter`): out (6,) deg moves
    toward ``target`` (deg) by at most rate * dt. lim: [max (6), rate (6), ramp_s, max_dt, safe_before]."""
    if safe and lim[SAFE_BEFORE] == 0.0:    # the safe state begins: ramp from here to zero in ramp_s
        for i in range(6):
            ramp_rate[i] = abs(out[i]) / lim[RAMP_S]
    lim[SAFE_BEFORE] = 1.0 if safe else 0.0
    dt = min(dt, lim[MAX_DT])
    for i in range(6):
        if safe:
            tg, r = 0.0, ramp_rate[i]
        else:
            m = lim[i]
            tg, r = min(max(target[i], -m), m), lim[RATE + i]
        step = r * dt
        d = tg - out[i]
        out[i] = tg if -step <= d <= step else (out[i] + step if d > 0 else out[i] - step)
