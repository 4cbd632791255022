"""The diagnosis' measured noise and its limits: fine load steps, noise-free data, too little data."""

import numpy as np
import pytest

from discovery.campaigns import campaign, start_model
from hil.testing import truth_with
from stiffness.data.residuals import pure_error, repeat_groups
from stiffness.diagnose.discovery import diagnose
from stiffness.errors import DataError


def test_repeats_of_fine_load_steps_are_not_chained_together():
    """50 N steps (24 per ramp): each load state is its own group and the noise is the optical noise."""
    data = campaign(truth_with([]), 30, configs=2, repeats=2, step_N=50)
    ctx = start_model().context(data)
    groups = repeat_groups(ctx)
    assert len(np.unique(groups)) >= 0.45 * ctx.n_readings      # ~2 readings per load state
    noise = pure_error(ctx, data.deflection)
    assert noise["position_mm"] == pytest.approx(0.03, rel=0.1)
    assert noise["rotation_deg"] == pytest.approx(0.002, rel=0.1)


def test_noise_free_repeats_give_no_measured_noise():
    data = campaign(truth_with([]), 31, configs=2, noise=False)
    assert pure_error(start_model().context(data), data.deflection) is None


def test_too_little_data_is_refused():
    data = campaign(truth_with([]), 32, configs=1, repeats=1)
    few = data.subset(np.arange(10))
    with pytest.raises(DataError, match="too few"):
        diagnose(start_model(), few)
