"""Kinematics: the batched DH chain agrees with pinocchio built from the same table."""

import numpy as np
import pinocchio as pin
import pytest

from stiffness.errors import ConfigError
from stiffness.kinematics.robot import BODIES, Robot


def test_batched_frames_match_pinocchio(robot):
    rng = np.random.default_rng(1)
    model = robot.pin_model
    data = model.createData()
    q = np.radians(rng.uniform(robot.limits_deg[:, 0], robot.limits_deg[:, 1], size=(20, 6)))
    F = robot.frames(q)
    S = robot.sensor_pose(F)
    for n in range(len(q)):
        pin.framesForwardKinematics(model, data, q[n])
        for k, name in enumerate(BODIES):
            M = data.oMf[model.getFrameId(name)]
            np.testing.assert_allclose(M.homogeneous, F[n, k + 1], atol=1e-12)
        np.testing.assert_allclose(data.oMf[model.getFrameId("sensor")].homogeneous, S[n], atol=1e-12)


def test_home_pose_matches_dh_table(robot):
    """At q = 0 the flange sits where the DH table puts it (worked by hand from the table)."""
    F = robot.frames(np.zeros((1, 6)))[0]
    # theta = offsets (0, 0, -90, 0, 0, 180): upper arm and forearm stretched forward (+x),
    # the elbow offset a3 = 45 mm pointing up, the tool axis along +x
    np.testing.assert_allclose(F[1, :3, 3], [0.410, 0.0, 0.865], atol=1e-12)
    np.testing.assert_allclose(F[2, :3, 3], [1.410, 0.0, 0.865], atol=1e-12)
    np.testing.assert_allclose(F[6, :3, 3], [0.410 + 1.0 + 1.0 + 0.210, 0.0, 0.865 + 0.045], atol=1e-12)
    np.testing.assert_allclose(F[6, :3, 2], [1.0, 0.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(F[7, :3, 3] - F[6, :3, 3], F[6, :3, :3] @ [0, 0, 0.25], atol=1e-12)


def test_joint_limits(robot):
    q = np.zeros((2, 6))
    q[1, 1] = 40.0  # A2 max is 35 deg
    ok = robot.within_limits(q)
    assert ok[0].all() and not ok[1, 1] and ok[1, [0, 2, 3, 4, 5]].all()


def test_bad_robot_config_names_key(tmp_path):
    p = tmp_path / "r.yaml"
    p.write_text("dh: {a_mm: [1, 2, 3], alpha_deg: [0,0,0,0,0,0], d_mm: [0,0,0,0,0,0]}\n"
                 "joint_limits_deg: [[-1,1],[-1,1],[-1,1],[-1,1],[-1,1],[-1,1]]\n")
    with pytest.raises(ConfigError, match=r"r.yaml: dh.a_mm .*6 values"):
        Robot.from_yaml(p)
    p.write_text("dh: {a_mm: [0,0,0,0,0,0], alpha_deg: [0,0,0,0,0,0], d_mm: [0,0,0,0,0,0]}\n"
                 "joint_limits_deg: [[-1,1],[-1,1],[-1,1],[-1,1],[-1,1],[-1,1]]\ntypo_key: 1\n")
    with pytest.raises(ConfigError, match="typo_key is not a known key"):
        Robot.from_yaml(p)
