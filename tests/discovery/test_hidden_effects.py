"""Discovery on campaigns with hidden effects (issue 3): the right effect at the right place is named
first; once it is added and fitted the residual falls to the noise; no hidden effect gives
no_missing_effect; two hidden effects are found one after the other; an effect outside the library
is not guessed.

Campaigns: 5 random configurations (a different seed per case), the paper's load ramps, 2 readings
per load state, optical noise 0.03 mm / 0.002 deg per component.
"""

import numpy as np
import pytest

from discovery.campaigns import campaign, start_model
from hil.testing import truth_with
from stiffness.diagnose.discovery import diagnose
from stiffness.fit.identify import fit
from stiffness.model.edit import add_effect

pytestmark = pytest.mark.slow

NOISE_MM, NOISE_DEG = 0.03, 0.002

CASES = [
    # (id, hidden entries, seed, starting model, expected (effect, location), axial-only except joint)
    ("backlash-j3", [{"effect": "backlash", "joint": 3, "lost_motion_deg": 0.02, "width_Nm": 5}], 1,
     "kr125_6dof", ("backlash", 3), None),
    ("backlash-j2-hard-step", [{"effect": "backlash", "joint": 2, "lost_motion_deg": 0.015, "width_Nm": 0.5}],
     2, "kr125_6dof", ("backlash", 2), None),
    ("hysteresis-j2", [{"effect": "hysteresis", "joint": 2, "offset_deg": -0.004}], 3, "kr125_6dof",
     ("hysteresis", 2), None),
    ("hysteresis-j4", [{"effect": "hysteresis", "joint": 4, "offset_deg": 0.006}], 4, "kr125_6dof",
     ("hysteresis", 4), None),
    ("two-slope-j1", [{"effect": "nonlinear_stiffness", "joint": 1, "form": "two_slope",
                       "soft_rad_per_Nm": 2.0e-7, "knee_Nm": 600}], 5, "kr125_6dof",
     ("nonlinear_stiffness", 1), None),
    ("cubic-j3", [{"effect": "nonlinear_stiffness", "joint": 3, "form": "cubic", "cubic_rad_per_Nm": -1.0e-7}],
     6, "kr125_6dof", ("nonlinear_stiffness", 3), None),
    ("bending-link2", [{"effect": "link_bending", "link": 2, "compliance_per_Nm2": 2.0e-7}], 7, "kr125_6dof",
     ("link_bending", 2), None),
    ("bending-link3", [{"effect": "link_bending", "link": 3, "compliance_per_Nm2": 3.0e-7}], 8, "kr125_6dof",
     ("link_bending", 3), None),
    ("misalignment-rz", [{"effect": "sensor_misalignment", "rz_deg": 2.0}], 9, "kr125_6dof",
     ("sensor_misalignment", None), None),
    ("misalignment-rxry", [{"effect": "sensor_misalignment", "rx_deg": 1.5, "ry_deg": -1.0}], 10, "kr125_6dof",
     ("sensor_misalignment", None), None),
    ("drift-x", [{"effect": "drift", "x_mm_per_min": 0.02}], 11, "kr125_6dof", ("drift", None), None),
    ("drift-z-rz", [{"effect": "drift", "z_mm_per_min": -0.015, "rz_deg_per_min": 0.0005}], 12, "kr125_6dof",
     ("drift", None), None),
    ("6dof-j4", [], 13, "kr125_axial", ("joint_6dof", 4), 4),
    ("6dof-j2", [], 14, "kr125_axial", ("joint_6dof", 2), 2),
]


@pytest.mark.parametrize("hidden, seed, start, expected, axial_except",
                         [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_hidden_effect_is_named_then_explained(hidden, seed, start, expected, axial_except):
    data = campaign(truth_with(hidden, axial_except), seed)
    d = diagnose(start_model(start), data)
    assert d.verdict == "missing_effect", d.message
    best = d.best
    assert (best.name, best.joint) == expected, [(c.name, c.joint, c.cv_improvement) for c in d.candidates[:3]]
    assert 0.0 < best.cv_improvement <= 1.0
    assert best.explanation.startswith(f"Missing: {expected[0]}")
    # add it, fit it: the residual falls to the noise
    fixed = fit(add_effect(d.fit.model, best.name, best.joint), data)
    assert fixed.rms_position_mm <= 1.15 * NOISE_MM
    assert fixed.rms_rotation_deg <= 1.15 * NOISE_DEG
    assert fixed.rms_position_mm < d.fit.rms_position_mm or fixed.rms_rotation_deg < d.fit.rms_rotation_deg


@pytest.mark.parametrize("seed", [15, 16, 17])
def test_no_hidden_effect_gives_no_missing_effect(seed):
    data = campaign(truth_with([]), seed)
    d = diagnose(start_model(), data)
    assert d.verdict == "no_missing_effect", [(c.name, c.joint, c.criteria) for c in d.candidates[:3]]
    assert d.best is None
    assert d.noise["position_mm"] == pytest.approx(NOISE_MM, rel=0.1)


def test_two_hidden_effects_are_found_one_after_the_other():
    hidden = [{"effect": "backlash", "joint": 3, "lost_motion_deg": 0.02, "width_Nm": 5},
              {"effect": "drift", "x_mm_per_min": 0.01}]
    data = campaign(truth_with(hidden), 18)
    found = []
    model = start_model()
    for _ in range(2):
        d = diagnose(model, data)
        assert d.verdict == "missing_effect"
        found.append((d.best.name, d.best.joint))
        model = fit(add_effect(d.fit.model, d.best.name, d.best.joint), data).model
    assert sorted(found, key=str) == sorted([("backlash", 3), ("drift", None)], key=str)
    final = diagnose(model, data)
    assert final.verdict == "no_missing_effect"
    assert final.fit.rms_position_mm <= 1.15 * NOISE_MM


def test_an_effect_outside_the_library_is_not_guessed():
    """A TCP-only deflection even in the force (a tool holder that slips the same way whichever way it
    is pushed) matches no library effect: the verdict is unexplained and names no effect."""
    data = campaign(truth_with([]), 19)
    tcp = data.body == 6
    data.deflection[tcp, 2] += 0.4 * (np.linalg.norm(data.wrench[tcp, :3], axis=1) / 1200.0) ** 2
    d = diagnose(start_model(), data)
    assert d.verdict == "unexplained", [(c.name, c.joint, c.criteria) for c in d.candidates[:3]]
    assert "does not guess" in d.message
    assert d.worst["body"] == "TCP"


def test_campaign_without_repeats_uses_the_stated_noise():
    """One reading per load state: no model-free noise; the diagnosis says so and still names effects."""
    clean = campaign(truth_with([]), 20, repeats=1)
    d = diagnose(start_model(), clean)
    assert d.noise is None and d.lack_of_fit["reference"] == "the model's stated noise"
    assert d.verdict == "no_missing_effect"
    hidden = campaign(truth_with([{"effect": "hysteresis", "joint": 3, "offset_deg": 0.005}]), 21, repeats=1)
    d = diagnose(start_model(), hidden)
    assert (d.verdict, d.best.name, d.best.joint) == ("missing_effect", "hysteresis", 3)


@pytest.mark.parametrize("transition_Nm, seed", [(60.0, 22), (150.0, 23)])
def test_smooth_hysteresis_fits_to_the_noise(transition_Nm, seed):
    """Gearbox hysteresis that moves between its branches over a transition torque (Dahl): the
    diagnosis names it first; added and fitted, the residual is within 10 % of the noise and the
    offset and the transition torque come back."""
    hidden = {"effect": "hysteresis", "joint": 4, "offset_deg": 0.006, "transition_Nm": transition_Nm}
    data = campaign(truth_with([hidden]), seed)
    d = diagnose(start_model(), data)
    assert (d.verdict, d.best.name, d.best.joint) == ("missing_effect", "hysteresis", 4)
    fixed = fit(add_effect(start_model(), "hysteresis", 4), data)
    assert fixed.rms_position_mm <= 1.10 * NOISE_MM
    assert fixed.rms_rotation_deg <= 1.10 * NOISE_DEG
    h = fixed.model.effects[-1].to_config()
    assert h["offset_deg"] == pytest.approx(0.006, rel=0.05)
    assert h["transition_Nm"] == pytest.approx(transition_Nm, rel=0.2)
