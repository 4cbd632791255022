"""The robot stub's modes from physics (``robot.frequencies: physics``, `hil.structure`) and the modal map
learned from a few of its poses (issue 52, item 5).

- The stub rings as its physics says: a tap test at two poses, identified as `stiffcomp modes` does, gives
  the modes the truth's stiffness and masses predict there, within 0.5 %.
- Its modes are a modal basis of the static deflection: any constant load settles to the static deflection.
- The map from the eight tapped corners of the circle's workspace predicts the first two modes within 5 % at
  ten held-out poses, where the physics prior alone (the model's masses, the service's tool: the truth's
  arm housing, forearm, rocker and tool differ) is off by more.
- A physics structure without masses, or with another arm's, is refused naming robot.masses.
"""

from __future__ import annotations

import numpy as np
import pytest

from hil.modal_survey import physics_scenario, service_map, tap_survey, true_modes, workspace_poses
from hil.robot_stub import RobotStub
from hil.scenario import load_scenario
from stiffness.dynamics.structure import ModeConfig
from stiffness.errors import ConfigError
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import ROOT

pytestmark = [pytest.mark.hil, pytest.mark.slow]


def physics_truth():
    """The scenario with the truth's modes from its own masses and a tool 20 % heavier, and its truth model."""
    sc = physics_scenario(0.2)
    return sc, StiffnessModel.from_yaml(sc.resolve(sc.truth))


def test_the_stub_rings_at_the_modes_its_physics_gives():
    sc, truth = physics_truth()
    poses = workspace_poses(sc, truth, 2, seed=1)
    np.testing.assert_allclose(tap_survey(sc, truth, poses), true_modes(sc, truth, poses), rtol=0.005)


def test_a_constant_load_settles_to_the_static_deflection():
    sc, truth = physics_truth()
    stub = RobotStub(truth, sc.robot, sc.payload)
    t = np.arange(0.0, 4.0, 5e-4)
    q = np.tile(sc.circle.center_q_deg, (len(t), 1))
    tcp = truth.robot.frames(np.radians(q))[:, 7, :3, 3]
    x = np.zeros((len(t), 3))
    x[200:] = [0.3e-3, -0.2e-3, 0.1e-3]
    out = stub.structure.respond(t, q, tcp, x)
    np.testing.assert_allclose(out[-1], x[-1], atol=1e-3 * np.abs(x[-1]).max())
    assert np.abs(out[200:600] - x[200:600]).max() > 0.5 * np.abs(x[-1]).max()      # it rang on the way


def test_the_map_from_eight_tapped_poses_predicts_held_out_poses_within_5_percent():
    sc, truth = physics_truth()
    measured_q = workspace_poses(sc, truth, 8, seed=0, corners=True)
    held_q = workspace_poses(sc, truth, 10, seed=52)
    mapped = service_map(sc)
    truth_hz = true_modes(sc, truth, held_q)
    prior = np.abs(mapped.predict(held_q)[0][:, :2] / truth_hz - 1).max()
    mapped.fit(measured_q, tap_survey(sc, truth, measured_q))
    after = np.abs(mapped.predict(held_q)[0][:, :2] / truth_hz - 1).max()
    assert after <= 0.05 and after < prior / 2, (prior, after)
    assert np.ptp(truth_hz[:, 0]) / truth_hz[:, 0].mean() > 0.05             # the modes do move over these poses


def test_physics_needs_masses_on_the_truths_arm(tmp_path):
    sc, truth = physics_truth()
    with pytest.raises(ConfigError, match="robot.masses"):
        RobotStub(truth, sc.robot.model_copy(update={"masses": None}), sc.payload)
    four = [{"hz": 10.0 + k, "damping": 0.03, "direction": d} for k, d in enumerate(np.eye(3).tolist())]
    four.append({"hz": 20.0, "damping": 0.03, "direction": [1.0, 0.0, 0.0]})
    with pytest.raises(ConfigError, match="robot.modes: 4 modes"):
        RobotStub(truth, sc.robot.model_copy(update={"modes": [ModeConfig(**m) for m in four]}), sc.payload)
    other = tmp_path / "other.yaml"
    other.write_text(f"extends: {ROOT / 'config/robots/kr125_masses.yaml'}\ndh: {{a_mm: [350, 1100, 41, 0, 0, 0]}}\n")
    with pytest.raises(ConfigError, match="robot.masses.*DH table or TCP"):
        RobotStub(truth, sc.robot.model_copy(update={"masses": str(other)}), sc.payload)


def test_the_scenarios_masses_are_found_beside_it(tmp_path):
    text = (ROOT / "config/hil/circle.yaml").read_text()
    for key in ("truth", "model", "service"):
        text = text.replace(f"\n{key}: ", f"\n{key}: {ROOT / 'config/hil'}/", 1)
    text = text.replace("  model: modal ", "  frequencies: physics\n  masses: masses.yaml\n  model: modal ", 1)
    (tmp_path / "masses.yaml").write_text(f"extends: {ROOT / 'config/hil/truth_masses.yaml'}\n")
    (tmp_path / "circle.yaml").write_text(text)
    sc = load_scenario(tmp_path / "circle.yaml")
    assert sc.robot.masses == str(tmp_path / "masses.yaml")
    truth = StiffnessModel.from_yaml(sc.resolve(sc.truth))
    assert RobotStub(truth, sc.robot, sc.payload).structure.physics is not None
