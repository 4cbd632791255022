"""Masses in the robot description, and a robot read from URDF: the same frames as its DH table."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from stiffness.errors import ConfigError
from stiffness.files.yaml_schema import dump_yaml, read_yaml
from stiffness.kinematics.robot import BODIES, Robot, read_extended
from stiffness.kinematics.statics import Statics
from stiffness.kinematics.urdf import urdf_text
from testlib.common import MODELS, ROOT
from tools.cli import main

ROBOTS = ROOT / "config" / "robots"


@pytest.fixture(scope="module")
def dh_robot() -> Robot:
    return Robot.from_yaml(ROBOTS / "kr125_masses.yaml")


@pytest.fixture(scope="module")
def urdf_robot() -> Robot:
    return Robot.from_yaml(ROBOTS / "kr125_urdf.yaml")


def pin_frames(robot: Robot, q: np.ndarray) -> np.ndarray:
    """Base poses of A1..A6, TCP and sensor from the robot's pinocchio model, (8, 4, 4)."""
    import pinocchio as pin

    pm = robot.pin_model
    pd = pm.createData()
    pin.framesForwardKinematics(pm, pd, q)
    return np.array([pd.oMf[pm.getFrameId(b)].homogeneous for b in (*BODIES, "sensor")])


joint_angles = st.lists(st.floats(-1.0, 1.0), min_size=6, max_size=6)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(u=joint_angles)
def test_shipped_urdf_kinematics_equal_the_dh_yaml(dh_robot, urdf_robot, u):
    """All DH frames, the TCP and the sensor agree to 1e-9 m (and 1e-9 in the rotation matrices), in
    the batched NumPy chain the model uses and in the pinocchio model the service uses."""
    lo, hi = np.radians(dh_robot.limits_deg).T
    q = lo + (np.asarray(u) + 1.0) / 2.0 * (hi - lo)
    F_dh, F_urdf = dh_robot.frames(q), urdf_robot.frames(q)
    np.testing.assert_allclose(F_urdf, F_dh, rtol=0, atol=1e-9)
    np.testing.assert_allclose(urdf_robot.sensor_pose(F_urdf), dh_robot.sensor_pose(F_dh), rtol=0, atol=1e-9)
    np.testing.assert_allclose(pin_frames(urdf_robot, q), pin_frames(dh_robot, q), rtol=0, atol=1e-9)
    np.testing.assert_allclose(pin_frames(urdf_robot, q)[:7], F_dh[0, 1:], rtol=0, atol=1e-9)


def test_shipped_urdf_has_the_yaml_limits_masses_and_statics(dh_robot, urdf_robot):
    np.testing.assert_allclose(urdf_robot.limits_deg, dh_robot.limits_deg, rtol=0, atol=1e-9)
    np.testing.assert_allclose(urdf_robot.link_mass, dh_robot.link_mass, rtol=0, atol=1e-9)
    np.testing.assert_allclose(urdf_robot.link_com, dh_robot.link_com, rtol=0, atol=1e-9)
    assert urdf_robot.balancer == dh_robot.balancer
    q = np.random.default_rng(3).uniform(-1.5, 1.5, size=(20, 6))
    a, b = Statics(urdf_robot, 60.0, (10, 0, 120))(q), Statics(dh_robot, 60.0, (10, 0, 120))(q)
    np.testing.assert_allclose(a.total, b.total, rtol=0, atol=1e-6)     # Nm, for torques of ~1e3 Nm
    assert np.abs(b.arm).max() > 100.0


def test_shipped_urdf_is_what_urdf_text_writes_from_the_yaml(dh_robot):
    """kr125.urdf is not edited by hand: regenerate it with urdf_text when kr125_masses.yaml changes."""
    assert (ROBOTS / "kr125.urdf").read_text() == urdf_text(dh_robot)


dh_values = st.fixed_dictionaries({
    "a_mm": st.lists(st.floats(-1500, 1500), min_size=6, max_size=6),
    "d_mm": st.lists(st.floats(-1500, 1500), min_size=6, max_size=6),
    "alpha_deg": st.lists(st.floats(-180, 180), min_size=6, max_size=6),
    "offset_deg": st.lists(st.floats(-179, 179), min_size=6, max_size=6),
})


@settings(max_examples=10, deadline=None)
@given(dh=dh_values, masses=st.lists(st.floats(0, 500), min_size=6, max_size=6),
       coms=st.lists(st.lists(st.floats(-800, 800), min_size=3, max_size=3), min_size=6, max_size=6),
       sensor_frame=st.integers(0, 6))
def test_any_dh_robot_round_trips_through_urdf(tmp_path_factory, dh, masses, coms, sensor_frame):
    folder = tmp_path_factory.mktemp("urdf")
    common = {"name": "r", "sensor": {"frame": sensor_frame, "xyz_mm": [5.0, -3.0, 40.0], "rpy_deg": [1.0, 2.0, 3.0]},
              "tcp": {"xyz_mm": [0.0, 10.0, 200.0], "rpy_deg": [0.0, 90.0, 0.0]}}
    links = [{"mass_kg": m, "com_mm": c} for m, c in zip(masses, coms)]
    dh_doc = {**common, "dh": dh, "joint_limits_deg": [[-170, 170]] * 6, "inertial": {"links": links}}
    (folder / "dh.yaml").write_text(dump_yaml(dh_doc))
    robot = Robot.from_yaml(folder / "dh.yaml")
    (folder / "r.urdf").write_text(urdf_text(robot))
    (folder / "u.yaml").write_text(dump_yaml({**common, "urdf": {"file": "r.urdf"}}))
    other = Robot.from_yaml(folder / "u.yaml")
    q = np.random.default_rng(0).uniform(-2.9, 2.9, size=(10, 6))
    np.testing.assert_allclose(other.frames(q), robot.frames(q), rtol=0, atol=1e-9)
    np.testing.assert_allclose(other.sensor_pose(other.frames(q)), robot.sensor_pose(robot.frames(q)), atol=1e-9)
    np.testing.assert_allclose(other.link_mass, robot.link_mass, atol=1e-9)
    # the first moments m c (a massless link has no centre): kg m to 1e-9
    np.testing.assert_allclose(other.link_mass[:, None] * other.link_com, robot.link_mass[:, None] * robot.link_com,
                               rtol=0, atol=1e-9)


# -- the URDF's chain must be a DH chain: errors name the file, the joint and what is wrong -----------

@pytest.fixture()
def urdf_folder(tmp_path, dh_robot):
    (tmp_path / "r.urdf").write_text(urdf_text(dh_robot))
    (tmp_path / "u.yaml").write_text("urdf: {file: r.urdf}\n")
    return tmp_path


def edit_urdf(folder, old: str, new: str, count: int = 1) -> None:
    p = folder / "r.urdf"
    text = p.read_text()
    assert old in text
    p.write_text(text.replace(old, new, count))


@pytest.mark.parametrize("old, new, message", [
    ('<axis xyz="0 0 1"/>', '<axis xyz="0 1 0"/>', r"r.urdf: joint 'joint1' .*about its frame's z axis"),
    ('<origin xyz="1.0 0.0 0.0"', '<origin xyz="1.0 0.05 0.0"',                      # joint 3, y offset
     r"r.urdf: joint 'joint3''s origin is not a DH transform from DH frame 1"),
    ('<origin xyz="0.0 0.0 0.0" rpy="0.0 0.0 0.0"/>', '<origin xyz="0.1 0.0 0.0" rpy="0.0 0.0 0.0"/>',
     r"joint 'joint1': its origin may only turn about z and lift along z"),
    ('name="joint6" type="revolute"', 'name="joint6" type="fixed"', r"needs six revolute joints in one chain"),
], ids=["axis-must-be-z", "origin-must-have-dh-form", "first-joint-on-the-root", "six-joints"])
def test_a_urdf_that_is_no_dh_chain_is_refused_naming_the_joint(urdf_folder, old, new, message):
    edit_urdf(urdf_folder, old, new)
    with pytest.raises(ConfigError, match=message):
        Robot.from_yaml(urdf_folder / "u.yaml")


def test_urdf_flange_must_exist(urdf_folder):
    (urdf_folder / "u.yaml").write_text("urdf: {file: r.urdf, flange: tool0}\n")
    with pytest.raises(ConfigError, match=r"flange = 'tool0' is not a frame of the URDF"):
        Robot.from_yaml(urdf_folder / "u.yaml")


def test_missing_or_broken_urdf(urdf_folder):
    (urdf_folder / "u.yaml").write_text("urdf: {file: nope.urdf}\n")
    with pytest.raises(ConfigError, match=r"u.yaml: urdf.file = '.*nope.urdf': file not found"):
        Robot.from_yaml(urdf_folder / "u.yaml")
    (urdf_folder / "bad.urdf").write_text("<robot name='x'><joint/></robot>")
    (urdf_folder / "u.yaml").write_text("urdf: {file: bad.urdf}\n")
    with pytest.raises(ConfigError, match=r"bad.urdf: pinocchio cannot read this URDF"):
        Robot.from_yaml(urdf_folder / "u.yaml")


# -- the inertial section ------------------------------------------------------------------------

def kr125_doc() -> dict:
    return read_extended(ROBOTS / "kr125_masses.yaml")     # the kinematic KR 125 and its masses, merged


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["inertial"]["links"][1].update(mass_kg=-5.0),
     r"r.yaml: inertial.links\[link 2\].mass_kg = -5.0: Input should be greater than or equal to 0"),
    (lambda d: d["inertial"]["links"][2].update(com_mm=[0.0, 2e4, 0.0]),
     r"r.yaml: inertial.links\[link 3\].com_mm.1 = 20000.0: Input should be less than or equal to 10000"),
    (lambda d: d["inertial"]["links"][2].update(com_mm=[0.0, 0.0]),
     r"r.yaml: inertial.links\[link 3\].com_mm = \[0.0, 0.0\]: .*at least 3 items"),
    (lambda d: d["inertial"]["links"].pop(), r"r.yaml: inertial.links has 5 entries: needs 6 values, one per joint \(got 5\)$"),
    (lambda d: d["inertial"]["links"][0].update(masss_kg=1.0), r"inertial.links\[link 1\].masss_kg is not a known key"),
    (lambda d: d["inertial"].update(balancer={"joint": 7, "share": 0.5}),
     r"inertial.balancer.joint = 7: Input should be less than or equal to 6"),
    (lambda d: d["inertial"].update(balancer={"joint": 2, "share": 1.5}),
     r"inertial.balancer.share = 1.5: Input should be less than or equal to 1"),
    (lambda d: d["inertial"].pop("links"), r"r.yaml: inertial.links is missing \(six entries"),
    (lambda d: d.update(urdf={"file": "kr125.urdf"}), r"r.yaml: give either dh .* or urdf"),
    (lambda d: d.pop("joint_limits_deg"), r"r.yaml: joint_limits_deg is missing"),
])
def test_bad_inertial_section_names_file_key_value_and_range(tmp_path, edit, message):
    doc = kr125_doc()
    edit(doc)
    (tmp_path / "r.yaml").write_text(dump_yaml(doc))
    with pytest.raises(ConfigError, match=message):
        Robot.from_yaml(tmp_path / "r.yaml")


@pytest.mark.parametrize("extra, message", [
    ({"joint_limits_deg": [[-1, 1]] * 6}, "joint_limits_deg is not allowed with urdf"),
    ({"inertial": {"links": kr125_doc()["inertial"]["links"]}}, "inertial.links is not allowed with urdf"),
])
def test_urdf_robot_takes_limits_and_masses_from_the_urdf(urdf_folder, extra, message):
    (urdf_folder / "u.yaml").write_text(dump_yaml({"urdf": {"file": "r.urdf"}, **extra}))
    with pytest.raises(ConfigError, match=message):
        Robot.from_yaml(urdf_folder / "u.yaml")


def test_masses_leave_the_kinematics_alone(dh_robot, tmp_path):
    doc = kr125_doc()
    del doc["inertial"]
    (tmp_path / "r.yaml").write_text(dump_yaml(doc))
    bare = Robot.from_yaml(tmp_path / "r.yaml")
    assert not bare.has_masses and bare.balancer is None and dh_robot.has_masses
    q = np.random.default_rng(5).uniform(-2, 2, size=(7, 6))
    np.testing.assert_array_equal(bare.frames(q), dh_robot.frames(q))
    for qk in q:
        np.testing.assert_array_equal(pin_frames(bare, qk), pin_frames(dh_robot, qk))


def test_urdf_values_out_of_range_are_a_config_error(urdf_folder):
    edit_urdf(urdf_folder, '<origin xyz="0.49 0.0 0.0" rpy="0 0 0"/><mass', '<origin xyz="0.49 0.0 12.0" rpy="0 0 0"/><mass')
    with pytest.raises(ConfigError, match=r"r.urdf \(read for .*u.yaml\): inertial.links\[link 2\].com_mm.2 = 12000.0: "
                                          r".*less than or equal to 10000"):
        Robot.from_yaml(urdf_folder / "u.yaml")


# -- issue 27, item 1: a link's <inertial> without a valid <mass> is refused, never made massless -------

@pytest.mark.parametrize("mass, missing", [
    ("", r"has no <mass> \(write <mass value=\"KG\"/>, or remove the <inertial> of a massless link\)"),
    ('<mass value="heavy"/>', r"has <mass value='heavy'>: the mass must be a finite number >= 0 \(kg\)"),
    ("<mass/>", r"has <mass> without its value attribute"),
    ('<mass value="-220.0"/>', r"has <mass value='-220.0'>: the mass must be a finite number >= 0"),
    ('<mass value="nan"/>', r"has <mass value='nan'>: the mass must be a finite number"),
], ids=["no-mass", "not-a-number", "no-value", "negative", "nan"])
def test_an_inertial_without_a_valid_mass_is_refused_naming_file_link_and_what_is_missing(urdf_folder, capsys,
                                                                                           mass, missing):
    """urdfdom drops such an inertial with one line on stderr: the 220 kg rocker would weigh nothing and joint
    2's static torque would drop from 840 to 629 Nm with exit 0. Robot.from_yaml refuses it; so does every
    command that loads the robot (exit 2, one line naming the file and the link)."""
    edit_urdf(urdf_folder, '<mass value="220.0"/>', mass)
    with pytest.raises(ConfigError, match=r"r.urdf: link 'link2': its <inertial> " + missing):
        Robot.from_yaml(urdf_folder / "u.yaml")
    model = read_yaml(MODELS / "kr125_6dof.yaml") | {"robot": str(urdf_folder / "u.yaml")}
    (urdf_folder / "m.yaml").write_text(dump_yaml(model))
    assert main(["torques", str(urdf_folder / "m.yaml"), "--q", "0", "-90", "90", "0", "90", "0"]) == 2
    err = capsys.readouterr().err
    assert f"{urdf_folder / 'r.urdf'}: link 'link2': its <inertial>" in err and "Traceback" not in err


def test_a_link_without_inertial_stays_massless(urdf_folder, dh_robot):
    """No <inertial> at all is a massless link on purpose (the URDF spec's way), not an error."""
    text = (urdf_folder / "r.urdf").read_text()
    start = text.index("<inertial>", text.index('<link name="link6">'))
    end = text.index("</inertial>", start) + len("</inertial>")
    (urdf_folder / "r.urdf").write_text(text[:start] + text[end:])
    robot = Robot.from_yaml(urdf_folder / "u.yaml")
    assert robot.link_mass[5] == 0.0
    np.testing.assert_allclose(robot.link_mass[:5], dh_robot.link_mass[:5], rtol=0, atol=1e-9)
