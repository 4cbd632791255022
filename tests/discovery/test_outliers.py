"""Robust identification (issue 12): 1 % of rows off by 0.4 mm, as occluded LEDs give.

The robust fit (the default) recovers the axial stiffness within 3 %, flags at least 80 % of the
bad rows, and at least 80 % of what it flags is bad. A hidden backlash is still named as backlash,
not taken for a cloud of outliers.
"""

import numpy as np
import pytest

from discovery.campaigns import campaign, start_model, with_gross_errors
from hil.testing import truth_with
from stiffness.diagnose.discovery import diagnose
from stiffness.fit.identify import fit
from stiffness.model.edit import add_effect

pytestmark = pytest.mark.slow

BACKLASH = {"effect": "backlash", "joint": 3, "lost_motion_deg": 0.02, "width_Nm": 5}


def axial(model) -> dict[int, float]:
    return {e.joint: e.theta[list(e.components).index("rz")] for e in model.effects
            if e.name == "joint_spring"}


def precision_recall(flagged: np.ndarray, bad: np.ndarray) -> tuple[float, float]:
    hit = np.isin(bad, flagged).sum()
    return hit / max(len(flagged), 1), hit / len(bad)


def assert_axial_within(fitted, truth, rel):
    got, want = axial(fitted), axial(truth)
    for j in range(1, 7):
        assert got[j] == pytest.approx(want[j], rel=rel), f"joint {j}"


@pytest.mark.parametrize("seed", [41, 42])
def test_gross_errors_are_flagged_and_do_not_bias_the_fit(seed):
    truth = truth_with([])
    data, bad = with_gross_errors(campaign(truth, seed), seed=seed)
    result = fit(start_model(), data)
    flagged = np.nonzero(result.outlier)[0]
    precision, recall = precision_recall(flagged, bad)
    assert recall >= 0.8 and precision >= 0.8, (precision, recall)
    assert result.outliers()["lines"] == data.line[flagged].tolist()
    assert_axial_within(result.model, truth, 0.03)
    # the residual of the rows kept is at the noise, not inflated by the bad rows
    assert result.rms_position_mm == pytest.approx(0.03, rel=0.1)


def test_plain_fit_flags_nothing():
    data, _ = with_gross_errors(campaign(truth_with([]), 43), seed=43)
    plain = fit(start_model(), data, robust=False)
    assert not plain.outlier.any() and plain.outliers() == {"count": 0, "lines": []}


def test_backlash_is_named_not_taken_for_outliers():
    truth = truth_with([BACKLASH])
    data, bad = with_gross_errors(campaign(truth, 1), seed=1)
    d = diagnose(start_model(), data)
    assert d.verdict == "missing_effect" and (d.best.name, d.best.joint) == ("backlash", 3), d.message
    precision, recall = precision_recall(np.nonzero(d.fit.outlier)[0], bad)
    assert recall >= 0.8 and precision >= 0.8, (precision, recall)
    with_backlash = add_effect(d.fit.model, d.best.name, d.best.joint)
    result = fit(with_backlash, data)
    precision, recall = precision_recall(np.nonzero(result.outlier)[0], bad)
    assert recall >= 0.8 and precision >= 0.8, (precision, recall)
    # the bad rows cost nothing: the fit equals the fit of the same campaign without them, within a
    # third of a standard error, and joints 1-5 are within 3 % of the truth. Joint 6 (the smallest
    # torques of this load point) is 5.6 % off on this seed even on the clean campaign, a limit of
    # the campaign and not of the robust fit, so it is held to the clean fit only.
    clean = fit(with_backlash, campaign(truth, 1), robust=False)
    got, ref, want = axial(result.model), axial(clean.model), axial(truth)
    se = {e.joint: e.std_error[list(e.components).index("rz")] for e in clean.model.effects
          if e.name == "joint_spring"}
    for j in range(1, 7):
        assert abs(got[j] - ref[j]) < se[j] / 3, f"joint {j}"
    for j in range(1, 6):
        assert got[j] == pytest.approx(want[j], rel=0.03), f"joint {j}"
