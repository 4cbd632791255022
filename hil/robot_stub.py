"""The robot stub: commanded joints and the process load in, the actual (deflected) TCP out.

The "real" robot is a truth stiffness model (YAML, the same format as the models). Its servos hold
the commanded joints exactly (the encoders read q_cmd); the arm deflects under the load by the
truth model's prediction (Eq. 4-7, the full loaded chain, every effect the truth holds):

    p_actual = p_TCP(q_cmd) + dp_truth(q_cmd, W_s)

W_s is the process force at the TCP through the arm's structure (`hil.structure`): by default the arm
rings (its modes carry the static deflection as oscillators, the load through a low-pass first), or it
follows the load through a critically damped low-pass at ``structure_hz``. Nothing in the loop reads the
actual pose (the PLC gets encoder values), so the stub evaluates a whole pass in one batch after it
(`actual`), the servos holding the commanded joints between PLC cycles.

History. The truth sees a pass as one load history in time order: one configuration, the cycle times
as the readings' times, so a history-dependent effect (hysteresis, `stiffness.effects.hysteresis`)
carries its state along the pass from a defined start (the first cycle, before the cut, unloaded).
A drift in the truth grows from the pass's first cycle as a thermal drift does; the service ignores
drift, so it stays in the compensated path error.

Static torque. The truth's backlash, nonlinear stiffness and hysteresis act at the joint's total
torque tau_s(q) + tau_ext (`stiffness.kinematics.statics`): tau_s from the truth's robot (its masses and balancer)
and the payload the sensor carries in this run (the scenario's ``payload``, `TruePayload.carried`, in
its gravity ``g_mps2``), the same bodies whose weight the virtual sensor reports. Not the truth model's
own ``payload`` key (what a campaign's sensor carried): the HIL's world decides what the arm holds. A
truth robot without masses has tau_s = 0 (`stiffness.kinematics.statics.statics_for`), as before robots had masses.
The deflection is loaded minus unloaded, f(tau_s + tau) - f(tau_s): the path was taught under the
arm's own weight.

Input effects. The arm deflects under the true wrench W; a misaligned sensor only reports it turned,
W_measured = L^-1 W with L = `StiffnessModel.input_map` (W_true = L W_measured, the model's
convention; `World.sensor_wrench` reports the same). The stub hands the truth that measured wrench,
and the truth's own input effects map it back to W.
"""

from __future__ import annotations

import numpy as np

from stiffness.data.campaign import Context
from stiffness.data.measurements import Dataset
from stiffness.kinematics.spatial import transform, transport_wrench
from stiffness.kinematics.statics import PayloadConfig, statics_for
from stiffness.model.stiffness_model import StiffnessModel

from .payload import TruePayload
from .structure import GRID_S, Structure, StructureConfig, physical_modes


class RobotStub:
    """The truth robot.

    Parameters
    ----------
    truth : StiffnessModel
    structure : StructureConfig or float
        The arm's structure (`hil.structure`); a number: the critically damped low-pass at that frequency
        (Hz; 0 = static).
    payload : a payload section (the scenario's ``payload``, `hil.payload.TruePayload`)
        What the arm carries at the sensor, in the static torque; None: the truth model's own
        ``payload`` (none when it has no such key).
    """

    def __init__(self, truth: StiffnessModel, structure: StructureConfig | float = 0.0, payload=None):
        self.truth = truth
        self.robot = truth.robot
        self.measured_from_true = np.linalg.inv(truth.input_map())          # L^-1
        if payload is None:
            self.statics = truth.statics()
            carried = truth.payload if truth.payload is not None else PayloadConfig()
        else:
            carried = TruePayload(payload).carried()
            self.statics = statics_for(truth.robot, carried, payload.g_mps2)
        physics = (physical_modes(structure, truth, carried) if isinstance(structure, StructureConfig)
                   and structure.model == "modal" and structure.frequencies == "physics" else None)
        self.structure = Structure(structure, physics)

    def structural_load(self, t: np.ndarray, force: np.ndarray) -> np.ndarray:
        """The force (N, 3) the arm feels at times ``t`` (uniformly spaced, s) for the process force."""
        return self.structure.load(t, force)

    def actual(self, t_log: np.ndarray, q_log: np.ndarray, force, t_start: float, t_end: float):
        """The actual TCP (N, 3, m) at the PLC's cycle times ``t_log`` for its commanded joints ``q_log`` (deg,
        held by the servos until the next cycle) and the process force ``force(t)`` (N, 3), over
        [t_start, t_end]; and the load the arm felt at those times (N, 3)."""
        grid = np.arange(t_start, t_end + GRID_S, GRID_S)
        F = self.structure.load(grid, force(grid))
        F_t = np.stack([np.interp(t_log, grid, F[:, k]) for k in range(3)], axis=1)
        if not self.structure.modal:
            return self.tcp(q_log, F_t, t_log), F_t
        k = np.clip(np.searchsorted(t_log, grid, side="right") - 1, 0, len(t_log) - 1)     # the servo holds q
        q_grid = np.asarray(q_log, dtype=float)[k]
        frames = self.robot.frames(np.radians(q_grid))
        x_static = self.tcp(q_grid, F, grid) - frames[:, 7, :3, 3]
        x = self.structure.respond(grid, q_grid, frames[:, 7, :3, 3], x_static)
        tcp = self.robot.frames(np.radians(np.atleast_2d(q_log)))[:, 7, :3, 3]
        return tcp + np.stack([np.interp(t_log, grid, x[:, j]) for j in range(3)], axis=1), F_t

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
