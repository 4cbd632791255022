"""Gross errors: rows of a campaign whose deflection neither the model nor their repeats explain.

An optical system that loses sight of an LED returns a frame that is off by tenths of a millimetre;
least squares has no defence against such a row. The fit (`identify.fit`) therefore reweights: after
each round the rows are scored and a row judged a gross error gets weight zero in the next round
(iteratively reweighted least squares with a hard-redescending weight, the classical data snooping
of geodesy). A row is judged a gross error when both

* its residual, normalised by a robust noise scale, is beyond the chi-square quantile
  ``1 - P_OUTLIER`` for its number m of measured components:

      z_i^2 = sum_k (r_ik / s_k)^2 > chi2.isf(P_OUTLIER, m_i),   s_k = 1.4826 median |r_.k|,

  (the median over the measured entries of the component's kind, position or rotation), and
* it disagrees with its repeats (the same body in the other readings of the same load state,
  `residuals.repeat_groups`) by as much: a gross error does not repeat, while the residual a missing
  physical effect leaves (a backlash, a drift, a knee) is the same in every repeat of a load state.
  Rows without repeats are judged on their residual alone.

The second test keeps a missing effect from being mistaken for a cloud of outliers; the diagnosis
then still sees it. With 10^4 rows the threshold gives about one false flag on clean data.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

P_OUTLIER = 1e-4
MAD_TO_SIGMA = 1.4826      # the median absolute deviation of a normal sample, in sigmas
FLOOR = 0.1                # the robust scale never falls below this share of the stated noise


def robust_scale(resid: np.ndarray, stated: np.ndarray) -> np.ndarray:
    """Noise per component (6,) from the median absolute residual of its kind (position, rotation).

    ``resid`` (N, 6) in mm / deg is NaN where not measured. The scale is at least FLOOR times the
    ``stated`` noise (6,): on noise-free data the residual is only the linearisation's, and rows
    must not be judged gross errors against it. A kind with no measured entry keeps ``stated``.
    """
    stated = np.asarray(stated, dtype=float)
    out = stated.copy()
    for sl in (slice(0, 3), slice(3, 6)):
        r = resid[:, sl]
        r = np.abs(r[np.isfinite(r)])
        if r.size:
            out[sl] = np.maximum(MAD_TO_SIGMA * float(np.median(r)), FLOOR * stated[sl])
    return out


def row_statistic(resid: np.ndarray, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per row, z^2 = sum over measured components of (r / sigma)^2, and the count m of them."""
    z = resid / sigma
    ok = np.isfinite(z)
    return np.sum(np.where(ok, z, 0.0) ** 2, axis=1), ok.sum(axis=1)


def repeat_deviation(resid: np.ndarray, group: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each row's residual minus the median residual of the other rows in its repeat group.

    Returns the deviation (N, 6), NaN for rows without a repeat, and the variance factor of the
    difference relative to one row's noise (1 + 1 / (k - 1) for k rows in the group).
    """
    dev = np.full_like(resid, np.nan)
    factor = np.ones(len(resid))
    order = np.argsort(group, kind="stable")
    starts = np.flatnonzero(np.r_[True, np.diff(group[order]) != 0])
    for rows in np.split(order, starts[1:]):
        k = len(rows)
        if k < 2:
            continue
        block = resid[rows]
        seen = np.isfinite(block).sum(axis=0)       # per component, how many rows of the group measure it
        for a, i in enumerate(rows):
            others = np.delete(block, a, axis=0)
            if k == 2:
                dev[i] = block[a] - others[0]
                continue
            # the median only over components another row measures: a component none of the others measures
            # (a part's rows measure the normal alone; the load's history rows nothing) has no repeat to differ from
            shared = seen - np.isfinite(block[a]) > 0
            dev[i, shared] = block[a, shared] - np.nanmedian(others[:, shared], axis=0)
        factor[rows] = 1.0 + 1.0 / (k - 1)
    return dev, factor


def gross_errors(resid: np.ndarray, sigma: np.ndarray, group: np.ndarray | None = None) -> np.ndarray:
    """Boolean (N,): the rows judged gross errors (see the module docstring).

    Parameters
    ----------
    resid : (N, 6) measured - predicted, mm / deg, NaN where not measured
    sigma : (6,) robust noise per component (`robust_scale`), mm / deg
    group : (N,) repeat group of each row (same body, same load state), or None for no repeats
    """
    z2, m = row_statistic(resid, sigma)
    limit = np.where(m > 0, chi2.isf(P_OUTLIER, np.maximum(m, 1)), np.inf)
    bad = z2 > limit
    if group is not None and bad.any():
        dev, factor = repeat_deviation(resid, group)
        d2, dm = row_statistic(dev, sigma)
        has_repeat = dm > 0
        bad &= ~has_repeat | (d2 / factor > limit)
    return bad
