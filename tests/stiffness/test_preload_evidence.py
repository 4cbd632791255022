"""An identified preload is called identified only when the data show its crossing (issue 27).

A fit with ``--preload identify`` at a joint whose data have no nonlinearity used to report crossings as
"identified" while the RMS did not move. Now `preload_fit.evidence` compares the fit's RMS with the same
model without that joint's nonlinearity and preload, and the note says the data show no crossing unless
the RMS moved by more than the noise allows. Small campaigns (TCP position only, three configurations,
a few solver evaluations) keep it quick; the control with a real backlash must still be identified.
"""

from __future__ import annotations

import pytest
from discovery.campaigns import campaign

from stiffness.fit.identify import fit
from stiffness.model.edit import add_effect
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import MODELS, ROOT

KR125 = ROOT / "config" / "robots" / "kr125.yaml"          # no masses: the prior is tau_s = 0
BACKLASH = {"effect": "backlash", "joint": 2, "lost_motion_deg": 0.02, "width_Nm": 40.0}


def model_with(extra=()) -> StiffnessModel:
    d = StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml").to_dict()
    d["robot"] = str(KR125)
    d["effects"] = d["effects"] + list(extra)
    return StiffnessModel.from_dict(d, "kr125_6dof")


def preload_fit(hidden, stages=None):
    data = campaign(model_with(hidden), seed=41, configs=3, repeats=1, step_N=600)
    data = data.subset(data.body == 6)                  # the TCP alone: a few rows, the same physics
    start = add_effect(model_with(), "backlash", 2, preload={"joint": 2})
    return fit(start, data, rounds=1, max_nfev=3, progress=None if stages is None else stages.append)


def test_a_preload_at_a_joint_without_nonlinearity_is_not_called_identified():
    stages: list[str] = []
    result = preload_fit([], stages)
    (note,) = result.preload
    (ev,) = result.preload_evidence
    assert not ev.identified and ev.moved < ev.allowed
    assert note.startswith("static torque of joint 2 not identified: the data show no crossing at this joint")
    assert "crossed at" not in note
    # the preload fit says what it does while it works (the CLI's Progress shows these on stderr)
    assert "round 1 of 1" in stages and stages[-1] == "checking each identified preload against the noise"
    assert any(s.startswith("round 1 of 1: ") and "evaluations of the" in s for s in stages)


def test_a_real_crossing_is_identified_with_the_rms_it_moved():
    result = preload_fit([BACKLASH])
    (note,) = result.preload
    (ev,) = result.preload_evidence
    assert ev.identified and ev.moved > 3 * ev.allowed
    assert note.startswith("static torque of joint 2 identified: crossed at external")
    assert f"the residual RMS moves by {100 * ev.moved:.1f} %" in note


def test_a_preload_at_a_joint_with_no_axial_effect_is_not_identified():
    """A preload entry written by hand for a joint with no effect at its total torque."""
    d = add_effect(model_with(), "backlash", 2, preload={"joint": 2}).to_dict()
    d["effects"] = [e for e in d["effects"] if e["effect"] != "backlash"]
    start = StiffnessModel.from_dict(d, "m")
    data = campaign(model_with(), seed=41, configs=3, repeats=1, step_N=600)
    result = fit(start, data.subset(data.body == 6), rounds=1, max_nfev=3)
    (ev,) = result.preload_evidence
    assert not ev.identified and ev.moved is None
    assert "no axial nonlinearity at this joint (an effect at the total torque) to cross" in result.preload[0]


@pytest.mark.parametrize("effect", ["hysteresis", "link_bending"])
def test_preload_is_refused_for_an_effect_that_cannot_use_one(effect):
    from stiffness.errors import ConfigError

    with pytest.raises(ConfigError, match=rf"--preload: effect {effect} cannot use a preload \(only an effect at "
                                          r"the joint's total torque can: backlash, nonlinear_stiffness\)"):
        add_effect(model_with(), effect, 2, preload={"joint": 2})
