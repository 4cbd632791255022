"""The robot stub: commanded joints and the process load in, the actual (deflected) TCP out.

The "real" robot is a truth stiffness model (YAML, the same format as the models). Its servos hold
the commanded joints exactly (the encoders read q_cmd); the arm deflects under the load by the
truth model's prediction (Eq. 4-7, the full loaded chain, every effect the truth holds):

    p_actual = p_TCP(q_cmd) + dp_truth(q_cmd, W_s)

W_s is the process force at the TCP seen through the arm's first mode: a critically damped
second-order low-pass at ``structure_hz`` (the arm does not follow the 400 Hz tooth passing; 0 makes
the deflection static). Nothing in the loop reads the actual pose (the PLC gets encoder values), so
the stub evaluates a whole pass in one batch after it.

History. The truth sees a pass as one load history in time order: one configuration, the cycle times
as the readings' times, so a history-dependent effect (hysteresis, `stiffness.effects.hysteresis`)
carries its state along the pass from a defined start (the first cycle, before the cut, unloaded).
A drift in the truth grows from the pass's first cycle as a thermal drift does; the service ignores
drift, so it stays in the compensated path error.

Static torque. The truth's backlash, nonlinear stiffness and hysteresis act at the joint's total
torque tau_s(q) + tau_ext (`stiffness.statics`): tau_s from the truth's robot (its masses and balancer)
and the payload the sensor carries in this run (the scenario's ``payload``, `TruePayload.carried`, in
its gravity ``g_mps2``), the same bodies whose weight the virtual sensor reports. Not the truth model's
own ``payload`` key (what a campaign's sensor carried): the HIL's world decides what the arm holds. A
truth robot without masses has tau_s = 0 (`stiffness.statics.statics_for`), as before robots had masses.
The deflection is loaded minus unloaded, f(tau_s + tau) - f(tau_s): the path was taught under the
arm's own weight.

Input effects. The arm deflects under the true wrench W; a misaligned sensor only reports it turned,
W_measured = L^-1 W with L = `StiffnessModel.input_map` (W_true = L W_measured, the model's
convention; `World.sensor_wrench` reports the same). The stub hands the truth that measured wrench,
and the truth's own input effects map it back to W.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from stiffness.context import Context
from stiffness.measurements import Dataset
from stiffness.model import StiffnessModel
from stiffness.spatial import transform, transport_wrench
from stiffness.statics import statics_for

from .payload import TruePayload


class RobotStub:
    """The truth robot.

    Parameters
    ----------
    truth : StiffnessModel
    structure_hz : float
        Natural frequency of the arm's first mode (Hz); 0 = static.
    payload : a payload section (the scenario's ``payload``, `hil.payload.TruePayload`)
        What the arm carries at the sensor, in the static torque; None: the truth model's own
        ``payload`` (none when it has no such key).
    """

    def __init__(self, truth: StiffnessModel, structure_hz: float = 0.0, payload=None):
        self.truth = truth
        self.robot = truth.robot
        self.structure_hz = float(structure_hz)
        self.measured_from_true = np.linalg.inv(truth.input_map())          # L^-1
        if payload is None:
            self.statics = truth.statics()
        else:
            self.statics = statics_for(truth.robot, TruePayload(payload).carried(), payload.g_mps2)

    def structural_load(self, t: np.ndarray, force: np.ndarray) -> np.ndarray:
        """The force (N, 3) the arm feels at times ``t`` (uniformly spaced, s) for the process force."""
        if self.structure_hz <= 0 or len(t) < 2:
            return np.asarray(force, dtype=float)
        w = 2 * np.pi * self.structure_hz
        fs = 1.0 / float(t[1] - t[0])
        b, a = signal.bilinear([w * w], [1.0, 2 * w, w * w], fs)         # critically damped
        return signal.lfilter(b, a, force, axis=0)

    def tcp(self, q_cmd_deg: np.ndarray, force_tcp: np.ndarray, t_s: np.ndarray) -> np.ndarray:
        """Actual TCP positions (m, base), (N, 3), for commanded joints (N, 6 deg) and true TCP forces
        (N, 3 N, base axes) at the cycle times ``t_s`` (N, s, strictly increasing: one load history)."""
        q = np.atleast_2d(np.asarray(q_cmd_deg, dtype=float))
        f = np.atleast_2d(np.asarray(force_tcp, dtype=float))
        t = np.atleast_1d(np.asarray(t_s, dtype=float))
        n = len(q)
        if len(t) != n or np.any(np.diff(t) <= 0):
            raise ValueError(f"RobotStub.tcp needs one strictly increasing time per cycle ({n} cycles, "
                             f"{len(t)} times)")
        F = self.robot.frames(np.radians(q))
        T_tcp_axes = transform(np.broadcast_to(np.eye(3), (n, 3, 3)), F[:, 7, :3, 3])
        W_tcp = np.concatenate([f, np.zeros_like(f)], axis=1)
        W_s = transport_wrench(W_tcp, T_tcp_axes, self.robot.sensor_pose(F))
        data = Dataset(t, np.full(n, "pass"), q, W_s @ self.measured_from_true.T, np.full(n, 6),
                       np.zeros((n, 6)))
        return F[:, 7, :3, 3] + self.truth.predict(Context(self.robot, data, self.statics))[:, :3] / 1000.0
