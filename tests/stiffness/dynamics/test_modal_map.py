"""The modal map (`stiffness.dynamics.modal_map`): the modes of a spring on a mass, the arm's inertia at the
TCP from pinocchio, invariances of the physics over the workspace, the correction recovering known factors
from a few poses, and the poses' file refused line by line."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stiffness.dynamics.modal_map import ArmInertia, Factors, ModalMap, modes, read_poses
from stiffness.errors import DataError
from stiffness.files.yaml_schema import read_yaml
from stiffness.kinematics.robot import load_robot
from stiffness.kinematics.statics import PayloadConfig
from stiffness.model.cartesian import tcp_compliance
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import ROOT

MASSES = load_robot(ROOT / "config/robots/kr125_masses.yaml")
MODEL = StiffnessModel.from_yaml(ROOT / "config/models/kr125_6dof.yaml")
TOOL = PayloadConfig(mass_kg=12.0, cog_mm=[0.0, 0.0, 110.0])
CENTRE = np.array([0.0, -60.0, 90.0, 0.0, 60.0, 0.0])


def kr125_map(tool=TOOL) -> ModalMap:
    return ModalMap(lambda q: tcp_compliance(MODEL, q), ArmInertia(MASSES, tool, arm=MODEL.robot))


@given(k=st.lists(st.floats(1e5, 1e8), min_size=3, max_size=3), m=st.lists(st.floats(1.0, 1e4), min_size=3, max_size=3),
       turn=st.floats(-np.pi, np.pi))
@settings(max_examples=60, deadline=None)
def test_springs_on_masses_ring_at_root_k_over_m_in_any_axes(k, m, turn):
    c, s = np.cos(turn), np.sin(turn)
    R = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]])
    hz, phi = modes(R @ np.diag(k) @ R.T, R @ np.diag(m) @ R.T)
    expected = np.sort(np.sqrt(np.array(k) / np.array(m)) / (2 * np.pi))
    np.testing.assert_allclose(hz, expected, rtol=1e-9)
    np.testing.assert_allclose(np.linalg.norm(phi, axis=0), 1.0)
    assert (np.diff(hz) >= 0).all()


def test_a_kg_at_the_tcp_is_a_kg_there_and_the_arms_inertia_scales_with_its_masses():
    T = MASSES.frames(np.radians(CENTRE)[None])[0]
    sensor = MASSES.sensor_pose(T[None])[0]
    at_tcp = np.linalg.solve(sensor, T[7][:, 3])[:3] * 1000.0             # the TCP in the sensor frame, mm
    arm, one = ArmInertia(MASSES, PayloadConfig(mass_kg=1.0, cog_mm=at_tcp.tolist())).at(CENTRE)
    np.testing.assert_allclose(one, np.eye(3), atol=1e-9)
    np.testing.assert_allclose(arm, arm.T, atol=1e-6)
    assert np.linalg.eigvalsh(arm).min() > 0
    heavier = MASSES.__class__(MASSES.config.model_copy(deep=True), "heavier")
    heavier.link_mass = MASSES.link_mass * 2.0
    np.testing.assert_allclose(ArmInertia(heavier, TOOL).at(CENTRE)[0], 2 * arm, rtol=1e-9)


def round_column():
    """The model with joint 1's spring tilting alike about x and y: its spring sits in the base's frame (DH
    frame 0), which does not turn with the arm, so only then is the arm the same at every q1."""
    data = read_yaml(ROOT / "config/models/kr125_6dof.yaml")
    first = next(e for e in data["effects"] if e["effect"] == "joint_spring" and e["joint"] == 1)
    first["ry_rad_per_Nm"] = first["rx_rad_per_Nm"]
    model = StiffnessModel.from_dict(data, base_dir=ROOT / "config/models")
    return ModalMap(lambda q: tcp_compliance(model, q), ArmInertia(MASSES, TOOL))


ROUND = round_column()


@given(turn=st.floats(-60.0, 60.0))
@settings(max_examples=8, deadline=None)
def test_turning_the_arm_about_its_base_turns_its_modes_and_keeps_their_frequencies(turn):
    q = CENTRE + [turn, 0, 0, 0, 0, 0]
    hz0, phi0 = ROUND.predict(CENTRE)
    hz, phi = ROUND.predict(q)
    np.testing.assert_allclose(hz, hz0, rtol=1e-6)           # the compliance probed at 1 N: 1e-7
    c, s = np.cos(np.radians(turn)), np.sin(np.radians(turn))
    turned = np.array([[c, -s, 0], [s, c, 0], [0, 0, 1.0]]) @ phi0[0]
    np.testing.assert_allclose(np.abs(np.einsum("ik,ik->k", turned, phi[0])), 1.0, atol=1e-6)


def test_the_modes_move_over_the_workspace_and_a_heavier_tool_lowers_them():
    m = kr125_map()
    near, far = CENTRE + [0, 20, -20, 0, 0, 0], CENTRE + [0, -15, 15, 0, 0, 0]
    hz = m.predict(np.array([near, CENTRE, far]))[0]
    assert np.ptp(hz[:, 0]) / hz[1, 0] > 0.03                       # the workspace moves them
    heavy = m.predict(CENTRE, Factors(tool_kg=40.0))[0]
    assert (heavy < m.predict(CENTRE)[0]).all()


def test_a_few_poses_recover_the_modes_of_known_factors_everywhere():
    m = kr125_map()
    true = Factors(stiffness=0.93, arm=1.12, tool_kg=16.0)
    rng = np.random.default_rng(3)
    poses = CENTRE + rng.uniform(-1, 1, (14, 6)) * [25, 12, 12, 10, 10, 10]
    measured, held = poses[:6], poses[6:]
    before = np.abs(m.predict(held)[0][:, :2] / m.predict(held, true)[0][:, :2] - 1).max()
    m.fit(measured, m.predict(measured, true)[0][:, :2])
    after = np.abs(m.predict(held)[0][:, :2] / m.predict(held, true)[0][:, :2] - 1).max()
    assert before > 0.03 and after < 0.003


def test_what_cannot_be_fitted_is_refused():
    m = kr125_map()
    with pytest.raises(DataError, match="one row of 1-3 frequencies per pose"):
        m.fit(np.array([CENTRE, CENTRE]), np.array([[10.0, 11.0]]))
    with pytest.raises(DataError, match="at least one frequency"):
        m.fit(np.array([CENTRE]), np.array([[np.nan, np.nan]]))


def test_masses_must_exist_and_hang_on_the_modelled_arm(tmp_path):
    with pytest.raises(DataError, match="no link masses"):
        ArmInertia(MODEL.robot, TOOL)
    other = tmp_path / "other.yaml"
    other.write_text(f"extends: {ROOT / 'config/robots/kr125_masses.yaml'}\ndh: {{a_mm: [350, 1100, 41, 0, 0, 0]}}\n")
    with pytest.raises(DataError, match="not .*kr125.yaml's"):
        ArmInertia(load_robot(other), TOOL, arm=MODEL.robot)


def test_the_poses_file_round_trips_and_names_each_bad_line(tmp_path):
    good = tmp_path / "poses.csv"
    good.write_text("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,f1_hz,f2_hz\n0,-60,90,0,60,0,10.2,11.3\n"
                    "10,-60,90,0,60,0,10.1,\n")
    q, f = read_poses(good, measured=True)
    np.testing.assert_array_equal(q[1], [10, -60, 90, 0, 60, 0])
    assert f[0].tolist() == [10.2, 11.3] and np.isnan(f[1, 1])
    bad = tmp_path / "bad.csv"
    bad.write_text("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,f1_hz\n0,-60,x,0,60,0,10\n0,-60,90,0,60,0,-3\n")
    with pytest.raises(DataError) as e:
        read_poses(bad, measured=True)
    text = str(e.value) + "".join(str(p) for p in e.value.problems)
    assert "line 2: q3_deg = 'x' is not a number" in text and "line 3: f1_hz = '-3'" in text
    unmeasured = tmp_path / "unmeasured.csv"
    unmeasured.write_text("q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg\n0,-60,90,0,60,0\n")
    assert read_poses(unmeasured, measured=False)[1].shape == (1, 0)
    with pytest.raises(DataError, match="line 1: missing column.*f1_hz"):
        read_poses(unmeasured, measured=True)


def test_a_singular_pose_is_refused_naming_it():
    on_the_axis = np.array([0.0, -109.46172, -0.0088259, 0.0, 60.0, 0.0])   # the TCP on the base's axis
    with pytest.raises(DataError, match=r"q = \[0.0, -109.462, -0.009.*no modes at a singular pose"):
        kr125_map().predict(on_the_axis)
    singular = ModalMap(lambda q: np.diag([1e-6, 1e-6, 0.0]), ArmInertia(MASSES, TOOL))
    with pytest.raises(DataError, match="compliance at the TCP is singular"):
        singular.predict(CENTRE)
