"""A modal survey in the HIL: the arm's first modes measured at poses over the circle's workspace, as a cell
would measure them (a tap test at each pose, identified as `stiffcomp modes` does), and the truth's own.

The workspace: the circle's centre moved within a box (``box_mm``, half-widths along the base's x, y, z)
with the tool as the circle holds it, each pose by inverse kinematics from the circle's centre. The robot
stub's structure decides what the modes are (``robot.frequencies``: the reach law, or physics from the
truth's own stiffness and masses, `hil.structure`). `physics_scenario` is the truth with physics' modes that
the service's side does not know exactly, `service_map` the map that side starts from. Used by
benchmarks/bench_modal_map.py and hil_tests/test_hil_modal_map.py.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pinocchio as pin

from service.config import load_config
from stiffness.dynamics.modal_map import ArmInertia, ModalMap
from stiffness.dynamics.modes import identify
from stiffness.kinematics.robot import load_robot
from stiffness.kinematics.statics import PayloadConfig
from stiffness.model.cartesian import tcp_compliance
from stiffness.model.stiffness_model import StiffnessModel

from .dynamics import tap_record
from .path import solve_ik
from .robot_stub import RobotStub
from .scenario import ROOT, Scenario, load_scenario

BOX_MM = (300.0, 300.0, 150.0)      # the workspace's half-widths around the circle's centre
TRUTH_MASSES = ROOT / "config/hil/truth_masses.yaml"       # the truth's own arm (its docstring says how it differs)
SERVICE_MASSES = ROOT / "config/robots/kr125_masses.yaml"  # what the service's side knows of it


def service_tool(scenario: Scenario) -> PayloadConfig:
    """What the scenario's service config says the sensor carries (its gravity section's set 0)."""
    carried = load_config(scenario.resolve(scenario.service)).gravity.payload_sets()[0]
    return PayloadConfig(mass_kg=carried.mass_kg, cog_mm=carried.cog_mm)


def physics_scenario(tool_error: float = 0.2) -> Scenario:
    """The default scenario with the truth's modes from physics (`TRUTH_MASSES`) and a tool ``tool_error``
    heavier than the service config's."""
    sc = load_scenario()
    sc.robot = sc.robot.model_copy(update={"frequencies": "physics", "masses": str(TRUTH_MASSES)})
    tool = sc.payload.tool.model_copy(update={"mass_kg": service_tool(sc).mass_kg * (1.0 + tool_error)})
    sc.payload = sc.payload.model_copy(update={"tool": tool})
    return sc


def service_map(scenario: Scenario) -> ModalMap:
    """The modal map the service's side starts from: its model's stiffness, `SERVICE_MASSES`, its tool."""
    model = StiffnessModel.from_yaml(scenario.resolve(scenario.model))
    inertia = ArmInertia(load_robot(SERVICE_MASSES), service_tool(scenario), arm=model.robot)
    return ModalMap(lambda q: tcp_compliance(model, q), inertia)


def workspace_poses(scenario: Scenario, truth: StiffnessModel, n: int, seed: int,
                    box_mm=BOX_MM, corners: bool = False) -> np.ndarray:
    """(n, 6) joint angles (deg) with the TCP in the box around the circle's centre, the tool as at the
    centre: drawn uniformly (``seed``), or, with ``corners``, the box's eight corners first."""
    robot = truth.robot
    q_c = np.radians(scenario.circle.center_q_deg)
    T_c = robot.frames(q_c[None])[0, 7]
    half = np.asarray(box_mm, dtype=float) / 1000.0
    if corners:
        grid = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], dtype=float)
        offsets = np.resize(grid, (n, 3)) * half
    else:
        offsets = np.random.default_rng(seed).uniform(-1.0, 1.0, (n, 3)) * half
    return np.array([np.degrees(solve_ik(robot, pin.SE3(T_c[:3, :3], T_c[:3, 3] + o), q_c)) for o in offsets])


def true_modes(scenario: Scenario, truth: StiffnessModel, poses: np.ndarray) -> np.ndarray:
    """(n, K) the stub's own modes' frequencies (Hz) at the poses, lowest first."""
    stub = RobotStub(truth, scenario.robot, scenario.payload)
    tcp = truth.robot.frames(np.radians(poses))[:, 7, :3, 3]
    return np.sort(stub.structure.frequencies(poses, tcp), axis=1)


def tap_survey(scenario: Scenario, truth: StiffnessModel, poses: np.ndarray, n_modes: int = 2,
               progress: Callable[[int, int], None] | None = None) -> np.ndarray:
    """(n, n_modes) the modes (Hz, lowest first) identified from a tap test at each pose."""
    out = []
    for i, q in enumerate(poses):
        found = identify(tap_record(scenario, truth, seed=17 + i, q_deg=q), n_modes)
        out.append(sorted(m.hz for m in found.structure.cfg.modes))
        if progress is not None:
            progress(i + 1, len(poses))
    return np.array(out)
