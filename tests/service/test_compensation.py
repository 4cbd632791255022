"""The real-time predictor agrees with the model core, and δq undoes the predicted deflection."""

from __future__ import annotations

import numpy as np
import pytest

from hil.testing import CONFIG
from service.compensation import FastPredictor
from service.errors import ModelUnsupportedError
from stiffness.data.measurements import Dataset
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import pose_error

MODELS = CONFIG / "models"


def random_cases(robot, n, seed):
    rng = np.random.default_rng(seed)
    lim = robot.limits_deg
    q = rng.uniform(lim[:, 0] * 0.9, lim[:, 1] * 0.9, size=(n, 6))
    w = rng.uniform(-1, 1, size=(n, 6)) * np.array([1500, 1500, 1500, 150, 150, 150])
    return q, w


@pytest.mark.parametrize("model_file", ["kr125_6dof.yaml", "kr125_axial.yaml"])
def test_agrees_with_model_predict_at_the_tcp(model_file):
    model = StiffnessModel.from_yaml(MODELS / model_file)
    fp = FastPredictor(model)
    q, w = random_cases(model.robot, 40, seed=11)
    data = Dataset(np.arange(40.0), np.array([f"c{i}" for i in range(40)]), q, w, np.full(40, 6),
                   np.zeros((40, 6)))
    exact, linear = model.predict(data), model.predict(data, linear=True)
    for k in range(40):
        fp.kinematics(np.radians(q[k]))
        dX = fp.deflection(fp.wrench_base(w[k].tolist()))
        got = np.concatenate([dX[:3] * 1000.0, np.degrees(dX[3:])])
        # the same first-order model: agreement to rounding
        np.testing.assert_allclose(got, linear[k], rtol=1e-9, atol=1e-12)
        # the model composes the loaded chain exactly: second-order terms only (mm deflections)
        np.testing.assert_allclose(got, exact[k], atol=2e-3 * np.abs(exact[k]).max())


def test_zero_load_gives_zero_deflection_and_correction():
    fp = FastPredictor(StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml"))
    q = np.radians([10, -70, 95, 15, 40, -20])
    fp.kinematics(q)
    dX = fp.deflection([0.0] * 6)
    assert not dX.any()
    assert not fp.correction(q, dX).any()


def test_deflection_is_linear_in_the_load():
    fp = FastPredictor(StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml"))
    fp.kinematics(np.radians([10, -70, 95, 15, 40, -20]))
    w1, w2 = np.array([100.0, -50, 300, 5, 2, -1]), np.array([-20.0, 80, 10, -3, 1, 4])
    d = fp.deflection((2 * w1 + 3 * w2).tolist())
    np.testing.assert_allclose(d, 2 * fp.deflection(w1.tolist()) + 3 * fp.deflection(w2.tolist()), rtol=1e-10)


def test_correction_moves_the_tcp_by_minus_the_deflection():
    model = StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml")
    q, w = random_cases(model.robot, 10, seed=5)
    errors: dict[int, list[float]] = {}
    for it in (0, 1, 3):
        fp = FastPredictor(model, damping=1e-6, refinement_iterations=it)
        errors[it] = []
        for k in range(10):
            qr = np.radians(q[k])
            fp.kinematics(qr)
            dX = fp.deflection(fp.wrench_base(w[k].tolist()))
            dq = fp.correction(qr, dX)
            errors[it].append(pose_error(fp, qr, dq, dX) / (np.linalg.norm(dX) + 1e-12))
    assert max(errors[0]) < 1e-2             # linear step: first-order exact
    assert max(errors[3]) < 1e-6             # Newton refinement removes the linearisation error
    assert np.mean(errors[1]) < np.mean(errors[0])


def test_an_effect_without_a_fast_path_term_is_refused_by_name(monkeypatch):
    """A library effect without a real-time term (as a new one could be) stops the start."""
    from stiffness.effects import Effect
    from stiffness.effects.hysteresis import Hysteresis

    monkeypatch.setattr(Hysteresis, "realtime", Effect.realtime)
    data = {"name": "m", "robot": str(CONFIG / "robots" / "kr125.yaml"),
            "effects": [{"effect": "joint_spring", "joint": 1, "rz_rad_per_Nm": 2e-7},
                        {"effect": "hysteresis", "joint": 3}]}
    model = StiffnessModel.from_dict(data, source="m.yaml")
    with pytest.raises(ModelUnsupportedError, match=r"m.yaml: effect hysteresis@joint3 is not supported"):
        FastPredictor(model)


def test_axial_effects_agree_with_the_model():
    """Backlash and nonlinear stiffness enter the fast path as functions of the joint torque."""
    import yaml

    data = yaml.safe_load((MODELS / "kr125_6dof.yaml").read_text())
    data["robot"] = str(CONFIG / "robots" / "kr125.yaml")
    data["effects"] += [
        {"effect": "backlash", "joint": 2, "lost_motion_deg": 0.02, "width_Nm": 50.0},
        {"effect": "nonlinear_stiffness", "joint": 3, "form": "cubic", "cubic_rad_per_Nm": 1e-7},
        {"effect": "nonlinear_stiffness", "joint": 1, "form": "two_slope", "soft_rad_per_Nm": 5e-8,
         "knee_Nm": 200.0},
    ]
    model = StiffnessModel.from_dict(data, source="axial.yaml")
    fp = FastPredictor(model)
    assert len(fp.axial) == 3
    q, w = random_cases(model.robot, 30, seed=21)
    data_ = Dataset(np.arange(30.0), np.array([f"c{i}" for i in range(30)]), q, w, np.full(30, 6),
                    np.zeros((30, 6)))
    linear = model.predict(data_, linear=True)
    springs_only = FastPredictor(StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml"))
    differs = 0
    for k in range(30):
        qr = np.radians(q[k])
        fp.kinematics(qr)
        dX = fp.deflection(fp.wrench_base(w[k].tolist()))
        got = np.concatenate([dX[:3] * 1000.0, np.degrees(dX[3:])])
        np.testing.assert_allclose(got, linear[k], rtol=1e-9, atol=1e-12)
        springs_only.kinematics(qr)
        d0 = springs_only.deflection(springs_only.wrench_base(w[k].tolist()))
        differs += not np.allclose(d0, dX, rtol=1e-6)
    assert differs == 30                       # the axial effects do contribute


def test_refinement_leaves_what_kinematics_computed_untouched():
    """The cycle calls kinematics() only when q changes: correction() must not disturb its results."""
    model = StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml")
    q, w = random_cases(model.robot, 3, seed=11)
    fp = FastPredictor(model, damping=1e-6, refinement_iterations=3)
    qr = np.radians(q[0])
    fp.kinematics(qr)
    before = [np.array(x, copy=True) for x in (fp.J, fp.J_pinv, fp.Ad, fp.R_s, fp.p_s, fp.T_tcp, fp.p_tcp)]
    dX = fp.deflection(fp.wrench_base(w[0].tolist()))
    dq1 = fp.correction(qr, dX)
    after = [np.array(x) for x in (fp.J, fp.J_pinv, fp.Ad, fp.R_s, fp.p_s, fp.T_tcp, fp.p_tcp)]
    for b, a in zip(before, after):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(fp.deflection(fp.wrench_base(w[0].tolist())), dX)
    np.testing.assert_array_equal(fp.correction(qr, dX), dq1)
