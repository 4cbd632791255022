"""What the virtual devices share: the path, the process force and the payload (the physical world).

Each device process builds its own `World` from the same scenario, so no state crosses processes
except through the real protocols (CAN to the service, Modbus between the service and the PLC).
Time ``t`` is in s since the cut started; before 0 the tool waits at the start point.

A misaligned sensor (a truth with an input effect) reports the true wrench turned: with the truth's
``L = StiffnessModel.input_map()`` (W_true = L W_measured), its gauges read L^-1 W_true, plus their
bias. The arm itself deflects under W_true (`RobotStub`).
"""

from __future__ import annotations

import numpy as np

from stiffness.kinematics.robot import Robot

from .milling import MillingForce
from .path import CirclePath
from .payload import TruePayload
from .scenario import Scenario


class World:
    """The scenario's path, process force and payload for one robot.

    Parameters
    ----------
    scenario : Scenario
    robot : Robot
    payload : the true payload and bias the sensor reports (the scenario's ``payload`` section, or any
        section with its keys; `hil.payload.TruePayload`); None: none
    input_map : (6, 6) the truth's L (W_true = L W_measured); None: a sensor aligned with its frame
    """

    def __init__(self, scenario: Scenario, robot: Robot, payload=None, input_map: np.ndarray | None = None):
        self.robot = robot
        self.path = CirclePath(robot, scenario.circle)
        self.milling = MillingForce(scenario.milling, scenario.circle.feed_mm_s, self.path.duration)
        self.axis_out = -self.path.R_tool[:, 2]
        self.gravity = TruePayload(payload) if payload is not None else None
        self.t_start = -self.path.lead_s
        self.t_end = self.milling.end_s + self.path.tail_s
        F = robot.frames(np.radians(scenario.circle.center_q_deg)[None])
        T_s = robot.sensor_pose(F)[0]
        self._R_s = T_s[:3, :3]
        self._lever = F[0, 7, :3, 3] - T_s[:3, 3]           # sensor origin -> TCP, base axes
        self._payload = self.gravity.wrench(self._R_s) if self.gravity is not None else np.zeros(6)
        self._bias = self.gravity.bias if self.gravity is not None else np.zeros(6)
        L = np.eye(6) if input_map is None else np.asarray(input_map, dtype=float)
        self.measured_from_true = np.linalg.inv(L)                 # L^-1

    PLAN_LOOKAHEAD_S = 0.05         # the PLC's plan_engagement is the engagement this far ahead

    def program_time(self, t: np.ndarray | float) -> np.ndarray | float:
        """The PLC program's time (s) at scenario time ``t``: from the pass's first cycle (the plan's time)."""
        return t - self.t_start

    def plan(self, t: float) -> tuple[float, float]:
        """What the virtual PLC writes for the feedforward at ``t``: the program's time and the engagement
        planned `PLAN_LOOKAHEAD_S` ahead."""
        return float(self.program_time(t)), float(self.milling.engagement(t + self.PLAN_LOOKAHEAD_S))

    def planned_force(self, t: np.ndarray) -> np.ndarray:
        """The force at full engagement without the tooth passing (N, base axes, (N, 3)): the process plan's."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        phi = self.path.angle(t)
        return self.milling.nominal(self.path.tangent(phi), self.path.outward(phi),
                                    np.broadcast_to(self.axis_out, (len(t), 3)))

    def force(self, t: np.ndarray) -> np.ndarray:
        """Process force on the cutter (N, base axes), (N, 3) for times ``t``."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        phi = self.path.angle(t)
        return self.milling.force(t, self.path.tangent(phi), self.path.outward(phi),
                                  np.broadcast_to(self.axis_out, (len(t), 3)))

    def sensor_wrench(self, t: np.ndarray) -> np.ndarray:
        """What the sensor's gauges see at times ``t``: L^-1 (the process force at the TCP plus the
        payload's weight) plus the bias, in sensor axes, moment about the sensor origin, (N, 6) in N, Nm.

        The tool keeps its orientation along the circle, so the sensor's axes and its lever to the TCP
        are those at the circle's centre (the correction turns them by hundredths of a degree).
        """
        f = self.force(t)
        R_s = self._R_s
        W_true = np.concatenate([f @ R_s, np.cross(self._lever, f) @ R_s], axis=1) + self._payload
        return W_true @ self.measured_from_true.T + self._bias
