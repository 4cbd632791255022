"""Backlash, nonlinear stiffness and hysteresis at the joint's total torque (issue 19, item 3 and 7).

A gearbox's play sits at zero total torque tau_s(q) + tau_ext; a campaign measures loaded minus
unloaded, so an axial effect adds f(tau_s + tau) - f(tau_s). Robots without masses keep tau_s = 0.
"""

from __future__ import annotations

import numpy as np
import pytest
from discovery.campaigns import campaign
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from service.compensation import FastPredictor
from stiffness.data.measurements import Dataset
from stiffness.errors import ConfigError
from stiffness.fit.identify import fit
from stiffness.kinematics.statics import PayloadConfig, Statics, static_regressor
from stiffness.model.preload_term import PreloadTerm
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.units import RAD_TO_DEG
from testlib.common import MODELS, ROOT

ROBOTS = ROOT / "config" / "robots"
MASSES = ROBOTS / "kr125_masses.yaml"
PAYLOAD = {"mass_kg": 80.0, "cog_mm": [0.0, 20.0, 150.0]}
AXIAL = [{"effect": "backlash", "joint": 2, "lost_motion_deg": 0.02, "width_Nm": 40.0},
         {"effect": "nonlinear_stiffness", "joint": 3, "form": "two_slope", "soft_rad_per_Nm": 1e-7,
          "knee_Nm": 300.0},
         {"effect": "hysteresis", "joint": 5, "offset_deg": -0.01, "transition_Nm": 20.0}]


def model_on(robot_file, extra=(), payload=None, base="kr125_6dof") -> StiffnessModel:
    d = StiffnessModel.from_yaml(MODELS / f"{base}.yaml").to_dict()
    d["robot"] = str(robot_file)
    d["effects"] = d["effects"] + list(extra)
    if payload is not None:
        d["payload"] = payload
    return StiffnessModel.from_dict(d, f"{base} on {robot_file.name}")


def tcp_data(robot, q_deg, wrench) -> Dataset:
    n = len(wrench)
    return Dataset(np.arange(float(n)), np.repeat(["c"], n) if np.ndim(q_deg) == 1 else
                   np.array([f"c{k}" for k in range(n)]), np.broadcast_to(q_deg, (n, 6)).copy(),
                   np.asarray(wrench, float), np.full(n, 6), np.zeros((n, 6)))


@settings(max_examples=15, deadline=None)
@given(st.lists(st.floats(-0.9, 0.9), min_size=6, max_size=6))
def test_no_external_load_no_deflection_whatever_the_preload(u):
    """Loaded minus unloaded: at zero external wrench every effect adds nothing, preload or not."""
    model = model_on(MASSES, AXIAL, PAYLOAD)
    lim = model.robot.limits_deg
    q = lim[:, 0] + (np.array(u) + 1) / 2 * (lim[:, 1] - lim[:, 0])
    data = tcp_data(model.robot, q, np.zeros((3, 6)))
    assume(np.abs(model.context(data).static_torque).max() > 100)     # the arm is preloaded (not near upright)
    np.testing.assert_array_equal(model.predict(data, linear=True), 0.0)


def test_the_backlash_step_sits_where_the_total_torque_crosses_zero():
    """Along a sweep of the external torque, the backlash's step is steepest at tau_ext = -tau_s."""
    model = model_on(MASSES, AXIAL[:1], PAYLOAD)
    springs = model_on(MASSES, (), PAYLOAD)
    q = np.array([0.0, -60.0, 80.0, 0.0, 40.0, 0.0])
    ctx0 = model.context(tcp_data(model.robot, q, np.zeros((1, 6))))
    tau_s = ctx0.static_torque[0, 1]
    expected = Statics(model.robot, PAYLOAD["mass_kg"], PAYLOAD["cog_mm"])(np.radians(q)).total[0, 1]
    assert tau_s == pytest.approx(expected, rel=1e-12) and abs(tau_s) > 500
    # a moment about the sensor's axis that loads joint 2: find the wrench direction from the model's own transport
    probe = ctx0.wrenches_at_frames(np.eye(6))[:, 1, 5]               # tau_2 per unit of each wrench component
    k = int(np.argmax(np.abs(probe)))
    scale = np.linspace(-3.0, 3.0, 601) * abs(tau_s) / probe[k]
    w = np.zeros((len(scale), 6))
    w[:, k] = scale
    data = tcp_data(model.robot, q, w)
    step = model.predict(data, linear=True) - springs.predict(data, linear=True)
    tau_ext = model.context(data).frame_wrench[:, 1, 5]
    slope = np.abs(np.gradient(np.linalg.norm(step, axis=1), tau_ext))
    assert tau_ext[np.argmax(slope)] == pytest.approx(-tau_s, abs=0.02 * abs(tau_s))


def test_a_robot_without_masses_is_unchanged_by_a_payload():
    """No inertial section: no static load is modelled, the payload's neither (tau_s = 0 exactly)."""
    bare = model_on(ROBOTS / "kr125.yaml", AXIAL, PAYLOAD)
    plain = model_on(ROBOTS / "kr125.yaml", AXIAL)
    rng = np.random.default_rng(3)
    lim = bare.robot.limits_deg
    q = rng.uniform(lim[:, 0], lim[:, 1], size=(20, 6))
    data = tcp_data(bare.robot, q, rng.normal(0, 600, size=(20, 6)))
    assert bare.statics() is None
    np.testing.assert_array_equal(bare.predict(data), plain.predict(data))


def test_the_service_evaluates_the_effects_at_the_total_torque_as_the_model_does():
    """FastPredictor, its payload from the gravity section (`carry`), equals predict(linear=True) to
    rounding over random configurations and loads: tau_s is formed again at each change of q."""
    model = model_on(MASSES, AXIAL, PAYLOAD)
    fp = FastPredictor(model, damping=1e-6)
    p = PayloadConfig.model_validate(PAYLOAD)
    fp.carry(p.mass_kg, np.array(p.cog_mm) / 1000.0, [0.0, 0.0, -9.81])
    blind = FastPredictor(model_on(ROBOTS / "kr125.yaml", AXIAL))
    rng = np.random.default_rng(11)
    lim = model.robot.limits_deg
    q = rng.uniform(lim[:, 0] * 0.9, lim[:, 1] * 0.9, size=(12, 6))
    w = rng.normal(0, 500, size=(12, 6)) * [1, 1, 1, 0.1, 0.1, 0.1]
    linear = model.predict(tcp_data(model.robot, q, w), linear=True)
    differs = 0
    for k in range(len(q)):
        for f in (fp, blind):
            f.reset_history()
            f.kinematics(np.radians(q[k]))
        dX = fp.deflection(fp.wrench_base(w[k].tolist()))
        np.testing.assert_allclose(np.concatenate([dX[:3] * 1e3, dX[3:] * RAD_TO_DEG]), linear[k],
                                   rtol=1e-9, atol=1e-12)
        differs += not np.allclose(dX, blind.deflection(blind.wrench_base(w[k].tolist())), rtol=1e-3)
    assert differs >= 10                                               # the preload matters


def test_a_preloaded_backlash_is_fitted_to_the_noise_by_the_preload_aware_model_only():
    """A campaign simulated from a truth with masses and a backlash at joint 2: the model that knows the
    masses fits it to the noise; the same model on the mass-free robot cannot."""
    truth = model_on(MASSES, AXIAL[:1], PAYLOAD, base="kr125_6dof")
    data = campaign(truth, seed=41, configs=5)
    aware = fit(model_on(MASSES, [dict(AXIAL[0], lost_motion_deg=0.0)], PAYLOAD), data)
    blind = fit(model_on(ROBOTS / "kr125.yaml", [dict(AXIAL[0], lost_motion_deg=0.0)]), data)
    assert aware.rms_position_mm <= 1.15 * 0.03 and aware.rms_rotation_deg <= 1.15 * 0.002
    assert blind.rms_position_mm > 1.1 * aware.rms_position_mm or blind.rms_rotation_deg > 1.1 * aware.rms_rotation_deg
    (b,) = [e for e in aware.model.effects if e.name == "backlash"]
    assert b.theta[0] * RAD_TO_DEG == pytest.approx(0.02, rel=0.1)


def test_the_model_payload_round_trips_and_bad_values_name_the_key(tmp_path):
    model = model_on(MASSES, AXIAL[:1], PAYLOAD)
    path = tmp_path / "m.yaml"
    model.to_yaml(path)
    again = StiffnessModel.from_yaml(path)
    assert again.payload == model.payload and again.payload.mass_kg == 80.0
    d = again.to_dict()
    d["payload"] = {"mass_kg": -3.0}
    with pytest.raises(ConfigError, match=r"m.yaml: payload.mass_kg = -3.0: Input should be greater"):
        StiffnessModel.from_dict(d, "m.yaml", robot=again.robot)
    d["payload"] = {"mass_kg": 3.0, "cog": [0, 0, 1]}
    with pytest.raises(ConfigError, match=r"m.yaml: payload.cog is not a known key"):
        StiffnessModel.from_dict(d, "m.yaml", robot=again.robot)


def test_a_robot_extends_another_and_a_loop_or_a_missing_base_is_named(tmp_path):
    from stiffness.kinematics.robot import Robot

    assert Robot.from_yaml(MASSES).has_masses and not Robot.from_yaml(ROBOTS / "kr125.yaml").has_masses
    (tmp_path / "a.yaml").write_text("extends: b.yaml\n")
    (tmp_path / "b.yaml").write_text("extends: a.yaml\n")
    with pytest.raises(ConfigError, match=r"extends = 'a.yaml' comes back to a file it extends"):
        Robot.from_yaml(tmp_path / "a.yaml")
    (tmp_path / "c.yaml").write_text("extends: nowhere.yaml\n")
    with pytest.raises(ConfigError, match=r"c.yaml: extends = 'nowhere.yaml': file .* not found"):
        Robot.from_yaml(tmp_path / "c.yaml")


def test_the_preload_module_runs_its_example():
    import doctest

    import stiffness.model.preload_term

    result = doctest.testmod(stiffness.model.preload_term)
    assert result.attempted > 0 and result.failed == 0


@settings(max_examples=25, deadline=None)
@given(st.lists(st.floats(-3.0, 3.0), min_size=6, max_size=6),
       st.lists(st.floats(-50.0, 50.0), min_size=18, max_size=18))
def test_an_identified_preload_adds_its_rows_of_the_static_regressor(q, values):
    """tau_s,j(q) gains phi_j(q) beta (stiffness.model.preload_term): the service's fast form equals the definition,
    at any configuration, for preloads at two joints, on a robot with masses and one without."""
    for robot_file in (ROBOTS / "kr125.yaml", MASSES):
        robot = model_on(robot_file).robot
        terms = [PreloadTerm(robot, j) for j in (2, 3)]
        preloads = [(t.joint, t.columns, np.array(values[: len(t.columns)])) for t in terms]
        with_pre = Statics(robot, 12.0, (0.0, 0.0, 100.0), preloads=preloads)
        without = Statics(robot, 12.0, (0.0, 0.0, 100.0))
        Y = static_regressor(with_pre.pm, with_pre.pd, np.array(q))
        expected = np.zeros(6)
        for j, cols, beta in preloads:
            expected[j - 1] += Y[j - 1, cols] @ beta
        np.testing.assert_allclose(with_pre.total_at(np.array(q)) - without.total_at(np.array(q)), expected,
                                   atol=1e-9 * (1 + np.abs(expected).max()))
