"""inf and NaN are refused in the service config: an infinite limit would silently disable it."""

import pytest

from hil.testing import write_config
from service.config import load_config
from service.errors import ServiceConfigError


@pytest.mark.parametrize("override, key", [
    ({"limits": {"max_correction_deg": float("inf")}}, "limits.max_correction_deg"),
    ({"limits": {"max_rate_deg_s": [1.0, 1.0, float("inf"), 1.0, 1.0, 1.0]}}, "limits.max_rate_deg_s"),
    ({"source": {"ati": {"counts_per_force": float("inf")}}}, "source.ati.counts_per_force"),
    ({"gravity": {"bias": [0.0, float("nan"), 0.0, 0.0, 0.0, 0.0]}}, "gravity.bias"),
])
def test_inf_and_nan_are_refused_naming_the_key(tmp_path, override, key):
    with pytest.raises(ServiceConfigError, match=key.replace(".", r"\.")):
        load_config(write_config(tmp_path, override))
