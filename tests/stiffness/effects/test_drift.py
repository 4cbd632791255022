"""drift: a base twist [v, w] (t - t0_config) growing within each configuration."""

import numpy as np

from hil.testing import model_with
from stiffness.data.measurements import Dataset


def test_offset_grows_with_time_in_each_configuration(robot):
    n = 6
    q = np.tile([10, -75, 90, 0, 75, 0], (n, 1))
    data = Dataset(np.array([0.0, 60, 120, 500, 560, 620]), np.array(["A", "A", "A", "B", "B", "B"]), q,
                   np.zeros((n, 6)), np.full(n, 6), np.zeros((n, 6)))
    m = model_with({"effect": "drift", "x_mm_per_min": 0.01, "z_mm_per_min": -0.02})
    d = m.predict(data)
    t_rel_min = np.array([0, 1, 2, 0, 1, 2.0])
    np.testing.assert_allclose(d[:, 0], 0.01 * t_rel_min, atol=1e-12)
    np.testing.assert_allclose(d[:, 2], -0.02 * t_rel_min, atol=1e-12)
    np.testing.assert_allclose(d[:, 3:], 0.0, atol=1e-15)
