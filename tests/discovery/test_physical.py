"""A candidate that passes the tests only with a compliance below zero is never named (a part read with a
wrong radius once named "link_bending at link 2, 1/EI = -4.15e-06 ± 3.5e-07 (not a physical, positive
compliance)"), while a component the noise leaves a little below zero does not stop one."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from stiffness.diagnose.discovery import NEGATIVE_SIGMA, Candidate
from stiffness.diagnose.explain import verdict_of
from stiffness.effects.link_bending import LinkBending

PASSED = {"cross_validation": True, "bic": True, "f_test": True}


def _candidate(estimate: float, se: float) -> Candidate:
    c = Candidate(LinkBending(2), 1, 0.02, math.nan, 0.45, -50.0, 1e-9, dict(PASSED), np.array([estimate]),
                  np.array([se]), np.zeros((1, 6)))
    c.named = c.significant and c.physical
    c.explanation = "Missing: link_bending"
    return c


@given(z=st.floats(-1e3, 1e3), se=st.floats(1e-9, 1e-6))
def test_physical_is_a_compliance_no_further_below_zero_than_the_limit(z, se):
    assert _candidate(z * se, se).physical == (z >= -NEGATIVE_SIGMA)


def test_a_significant_negative_compliance_is_not_named_and_the_verdict_says_why():
    lof = {"worst_body": 1.0, "threshold": 1.5, "position": 1.0, "rotation": math.nan, "reference": "the noise"}

    class Fit:
        rms_position_mm, rms_rotation_deg = 0.03, math.nan

        @staticmethod
        def rms_text():
            return "0.0300 mm"

    verdict, message = verdict_of([_candidate(-4.15e-6, 3.5e-7)], lof, Fit())
    assert verdict == "no_missing_effect" and "link_bending passes the tests only with a negative compliance" in message
    verdict, _ = verdict_of([_candidate(4.15e-6, 3.5e-7)], lof, Fit())
    assert verdict == "missing_effect"
