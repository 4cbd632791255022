"""Properties of partial measurements and identifiability over wide inputs (hypothesis)."""

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from stiffness.data.measurements import Dataset, read_measurements
from stiffness.fit.identifiability import unidentifiable, unidentifiable_information


def _masks(n):
    # every row measures at least one component
    return arrays(bool, (n, 6)).map(lambda m: np.where(m.any(axis=1, keepdims=True), m, np.eye(6, dtype=bool)[0]))


@settings(max_examples=25, deadline=None)
@given(mask=_masks(6), seed=st.integers(0, 2**16))
def test_any_measured_subset_round_trips_through_the_file(tmp_path_factory, mask, seed):
    rng = np.random.default_rng(seed)
    n = len(mask)
    d = Dataset(np.arange(n, dtype=float), np.array(["C1"] * n), np.zeros((n, 6)), rng.normal(size=(n, 6)),
                rng.integers(0, 7, n), np.where(mask, np.round(rng.normal(size=(n, 6)), 4), np.nan))
    path = tmp_path_factory.mktemp("rt") / "d.csv"
    d.to_csv(path)
    back = read_measurements(path)
    np.testing.assert_array_equal(back.measured, mask)
    np.testing.assert_allclose(back.deflection[mask], d.deflection[mask], atol=1e-6)


@settings(max_examples=40, deadline=None)
@given(seed=st.integers(0, 2**16), dead=st.integers(0, 4), log_scale=arrays(float, 5, elements=st.floats(-4, 4)))
def test_unidentifiable_is_what_no_data_can_see_whatever_the_units(seed, dead, log_scale):
    """A column that repeats another (two parameters only seen in sum) and a zero column are named,
    the rest not; rescaling the parameters (their units) by up to 10^4 each, eight decades between
    two, changes nothing. (The fit scales each parameter by its `Param.scale` before this test, so
    its columns differ by far less; a column below 1e-12 of the largest counts as zero, see
    `test_a_column_far_below_the_others_counts_as_zero`.)"""
    rng = np.random.default_rng(seed)
    J = rng.normal(size=(40, 5))
    J[:, (dead + 1) % 5] = 2.0 * J[:, dead]          # only a combination of the two is seen
    zero = (dead + 3) % 5
    J[:, zero] = 0.0
    want = np.zeros(5, bool)
    want[[dead, (dead + 1) % 5, zero]] = True
    np.testing.assert_array_equal(unidentifiable(J), want)
    scaled = J * 10.0 ** log_scale
    np.testing.assert_array_equal(unidentifiable(scaled), want)
    np.testing.assert_array_equal(unidentifiable_information(scaled.T @ scaled), want)


def test_a_column_far_below_the_others_counts_as_zero():
    """The documented limit of the invariance: a column below 1e-12 of the largest is no information."""
    J = np.random.default_rng(1).normal(size=(40, 3))
    J[:, 2] *= 1e-13
    np.testing.assert_array_equal(unidentifiable(J), [False, False, True])
    J[:, 2] *= 1e3                                   # 1e-10: seen, and independent of the others
    np.testing.assert_array_equal(unidentifiable(J), [False, False, False])
