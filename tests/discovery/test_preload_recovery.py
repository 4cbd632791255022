"""The loop on preloaded campaigns, as a script follows `diagnose --json`: diagnose -> add the first named
effect (its effect, joint and entry, nothing else) -> fit, until nothing is missing.

The truth carries masses 50 % off the shipped KR 125 ones (1.5 x; and 0.5 x for the backlash from the
shipped masses) and its balancer, so its backlash and soft zone sit at a static torque the start does not know: the loop must name exactly the truth's effect at its
joint with its preload, and end within 1.15 x the noise, starting from the shipped masses and from a
robot with no masses at all; a linear truth (the control) gives nothing.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from discovery.campaigns import campaign
from service.compensation import FastPredictor
from stiffness.diagnose.discovery import diagnose
from stiffness.diagnose.report import to_dict
from stiffness.errors import ConfigError
from stiffness.files.yaml_schema import dump_yaml, read_yaml
from stiffness.fit.identify import fit
from stiffness.model.edit import add_effect
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.units import RAD_TO_DEG
from testlib.common import MODELS, ROOT
from tools.common import to_jsonable

pytestmark = pytest.mark.slow

ROBOTS = ROOT / "config" / "robots"
ADD_OPTIONS = ("preload",)      # the options of `stiffcomp model add` a diagnosis entry may carry
NOISE_MM, NOISE_DEG = 0.03, 0.002
STEP_N = 300           # load steps of the campaign ramps (N); coarser ramps leave a crossing between two load states
BACKLASH = {"effect": "backlash", "joint": 2, "lost_motion_deg": 0.02, "width_Nm": 40.0}
SOFT_ZONE = {"effect": "nonlinear_stiffness", "joint": 3, "form": "two_slope", "soft_rad_per_Nm": 3e-7,
             "knee_Nm": 300.0}


def robot_scaled(tmp_path, factor: float):
    """A robot file extending kr125_masses.yaml with every link's mass times ``factor``."""
    d = read_yaml(ROBOTS / "kr125_masses.yaml")
    d["extends"] = str(ROBOTS / "kr125.yaml")
    for link in d["inertial"]["links"]:
        link["mass_kg"] *= factor
    path = tmp_path / f"kr125_masses_x{factor:g}.yaml"
    path.write_text(dump_yaml(d))
    return path


def model_on(robot_file, extra=()) -> StiffnessModel:
    d = StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml").to_dict()
    d["robot"] = str(robot_file)
    d["effects"] = d["effects"] + list(extra)
    return StiffnessModel.from_dict(d, f"kr125_6dof on {robot_file.name}")


def loop(model: StiffnessModel, data, rounds: int = 3):
    """Diagnose, add the named effect as `diagnose --json` says (its effect, joint and entry, nothing else: a
    key of the entry that is no parameter of the effect is an option of `model add`), fit; returns the
    effects named in order, their texts, and the last fit."""
    named, texts = [], []
    for _ in range(rounds):
        d = diagnose(model, data)
        result = d.fit
        advice = json.loads(json.dumps(to_jsonable(to_dict(d))))          # what a script reads
        best = advice["candidates"][0] if advice["candidates"] and advice["candidates"][0]["significant"] else None
        if best is None:
            return named, texts, result, d
        named.append((best["effect"], best["joint"]))
        texts.append(advice["message"])
        entry = dict(best["entry"])
        options = {k: entry.pop(k) for k in ADD_OPTIONS if k in entry}
        shape = {k: v for k, v in entry.items() if k not in ("effect", "joint")}
        preload = {"joint": best["joint"]} if options.get("preload") == "identify" else None
        model = fit(add_effect(result.model, best["effect"], best["joint"], shape, preload=preload), data).model
    return named, texts, result, d


CASES = [("backlash-j2", [BACKLASH], 1.5, 41, ("backlash", 2)),
         ("soft-zone-j3", [SOFT_ZONE], 1.5, 43, ("nonlinear_stiffness", 3)),
         ("linear-control", [], 1.5, 45, None)]
STARTS = ["kr125_masses.yaml", "kr125.yaml"]
# (start, case): every case from both starts, and the truth 50 % lighter from the shipped masses
RUNS = [(start, c) for c in CASES for start in STARTS] + [
    ("kr125_masses.yaml", ("backlash-j2-lighter", [BACKLASH], 0.5, 47, ("backlash", 2)))]


@pytest.mark.parametrize("start, hidden, factor, seed, expected", [(s, *c[1:]) for s, c in RUNS],
                         ids=[f"{c[0]}-{s.removesuffix('.yaml')}" for s, c in RUNS])
def test_the_loop_names_the_preloaded_effect_and_ends_at_the_noise(tmp_path, start, hidden, factor, seed, expected):
    truth = model_on(robot_scaled(tmp_path, factor), hidden)
    data = campaign(truth, seed=seed, configs=6, step_N=STEP_N)
    named, texts, result, last = loop(model_on(ROBOTS / start), data)
    assert named == ([expected] if expected else []), texts
    assert last.verdict == "no_missing_effect", last.message
    assert result.rms_position_mm <= 1.15 * NOISE_MM and result.rms_rotation_deg <= 1.15 * NOISE_DEG
    if expected:
        text = texts[0]
        assert "at zero total torque: crossed at external" in text and "the masses are wrong or missing" in text
        assert "-0 Nm" not in text
        assert any(e.kind == "static" and e.joint == expected[1] for e in result.model.effects)
        assert any(f"static torque of joint {expected[1]} identified" in n for n in result.preload)
    if expected == ("backlash", 2) and factor > 1:        # C1 crossing lies beyond its load range
        assert "preloaded beyond the load range in C1" in texts[0]
    print(f"{start} {named}: end {result.rms_position_mm / NOISE_MM:.3f} x / {result.rms_rotation_deg / NOISE_DEG:.3f} x"
          " the noise", texts[:1])


def test_a_preload_asked_for_is_identified_from_no_masses_stored_and_used_by_the_service(tmp_path):
    """`model add ... --preload identify` on a robot without masses: fit starts where the data step, ends
    at the noise, names the configuration beyond its load range; the YAML round-trips the identified
    static torque and the service's FastPredictor evaluates the backlash where the model does."""
    truth = model_on(robot_scaled(tmp_path, 1.5), [BACKLASH])
    data = campaign(truth, seed=41, configs=6, step_N=STEP_N)
    result = fit(add_effect(model_on(ROBOTS / "kr125.yaml"), "backlash", 2, preload={"joint": 2}), data)
    assert result.rms_position_mm <= 1.15 * NOISE_MM and result.rms_rotation_deg <= 1.15 * NOISE_DEG
    (note,) = result.preload
    assert "preloaded beyond the load range in C1" in note and "stay at the prior" in note
    path = tmp_path / "fitted.yaml"
    result.model.to_yaml(path)
    again = StiffnessModel.from_yaml(path)
    assert again.statics() is not None and again.robot.has_masses is False
    # the YAML keeps 6 digits: the prediction moves by far less than the noise (1 % of the rotation noise)
    np.testing.assert_allclose(again.predict(data), result.model.predict(data), rtol=0, atol=0.01 * NOISE_DEG)
    ctx = again.context(data)
    truth_ctx = truth.context(data)
    for c in (1, 3):                     # configurations crossed within their load range: tau_s recovered
        m = ctx.config == c
        assert ctx.static_torque[m, 1][0] == pytest.approx(truth_ctx.static_torque[m, 1][0], abs=60.0)
    fp = FastPredictor(again, damping=1e-6)
    rows = np.nonzero(data.body == 6)[0][::97]
    linear = again.predict(data, linear=True)
    for r in rows:
        fp.reset_history()
        fp.kinematics(np.radians(data.q_deg[r]))
        dX = fp.deflection(fp.wrench_base(data.wrench[r].tolist()))
        np.testing.assert_allclose(np.concatenate([dX[:3] * 1e3, dX[3:] * RAD_TO_DEG]), linear[r],
                                   rtol=1e-6, atol=1e-9)
    d = again.to_dict()
    d["preload"] = [{"joint": 2, "mass_kg": 3.0}]
    with pytest.raises(ConfigError, match=r"m.yaml: preload\[0\]: mass_kg is not a key of effect 'preload'"):
        StiffnessModel.from_dict(d, "m.yaml", robot=again.robot)
