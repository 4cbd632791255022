"""The discovery loop closed in the loop: the robot stub's truth holds a backlash in joint 3 that the
service's model lacks. The compensated path error E1 with the fitted 6-DoF model; `diagnose` on a
campaign simulated from the same truth names the backlash at joint 3; with it added and fitted the
compensated path error E2 is smaller than E1. The passes run in lock step (`hil.lockstep`): what the test
holds is the models', and real time adds nothing to it but three process start-ups a pass.
"""

from __future__ import annotations

from stiffness.diagnose.discovery import diagnose
from stiffness.fit.identify import fit
from stiffness.model.edit import add_effect
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.plan.simulate import Campaign
from testlib.hil import EXAMPLES, MODELS, compensated, mean_error, scenario, write_model

TRUTH = EXAMPLES / "truth_backlash.yaml"


def test_path_error_falls_once_the_diagnosed_backlash_is_added(tmp_path):
    data = Campaign.from_yaml(EXAMPLES / "campaign_backlash.yaml").run()
    d = diagnose(StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml"), data)
    assert d.verdict == "missing_effect", d.message
    assert (d.best.name, d.best.joint) == ("backlash", 3)
    # bounded fits: the service refuses a model with a negative compliance (an unbounded fit leaves some)
    before = write_model(fit(d.fit.model, data, nonnegative=True).model, tmp_path / "6dof.yaml")
    fixed = fit(add_effect(d.fit.model, d.best.name, d.best.joint), data, nonnegative=True)
    after = write_model(fixed.model, tmp_path / "6dof_backlash.yaml")
    sc = scenario()
    _, ev1 = compensated(sc, TRUTH, before, tmp_path / "before", lockstep=True)
    _, ev2 = compensated(sc, TRUTH, after, tmp_path / "after", lockstep=True)
    e1, e2 = mean_error(ev1), mean_error(ev2)
    print(f"E1 {e1:.4f} mm, E2 {e2:.4f} mm")
    assert e2 < 0.8 * e1, (e1, e2)
