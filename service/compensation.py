"""The real-time predictor: TCP deflection from the sensor wrench, and the joint correction δq_r.

Deflection (Eq. 4-5, linearised). Joint i's spring sits in DH frame i-1, with base pose T_i and
motion adjoint Ad_i = [[R_i, [p_i]x R_i], [0, R_i]]. The external wrench w0 = [F; M0] (base axes,
moment about the base origin; M0 = M + p_s x F for a moment M about the sensor origin p_s) reaches
frame i-1 as W_i = Ad_i^T w0 (Eq. 4, unloaded geometry). The spring twists by delta_i = C_i W_i
(C_i diagonal, m/N and rad/Nm); in base coordinates that twist is Ad_i delta_i, so

    [v0; dr] = sum_i Ad_i C_i Ad_i^T w0,      dX = [v0 + dr x p_tcp ; dr]      (m, rad, base axes)

the first-order term of `stiffness.model.stiffness_model.StiffnessModel.predict` (the tests check the agreement).
Pinocchio gives the frames and the Jacobian in one forward pass; the rest is four small NumPy calls.

Correction (the paper's δq_r). The commanded joints must move the unloaded TCP by -dX:

    δq = -J^T (J J^T + λ² I)^-1 dX

with J the TCP Jacobian [v; ω] in base axes and λ a small damping for wrist singularities. With
``refinement_iterations`` > 0, Newton steps on the full kinematics remove the linearisation error:
δq += J(q+δq)^+ (X_target - X(q + δq)).

Effects. Every effect of the model enters this path through the terms it returns itself
(`Effect.realtime`), which `service.fast_effects` assembles: diagonal compliances, functions of joint i's
torque tau_i = W_i[rz] added to its axial twist, history terms (a state fed tau_i every cycle), 6x6
compliances at a DH frame, and the input effects in the sensor's rotation; an ignored effect is logged
once. An effect without a real-time term is refused at start-up (ModelUnsupportedError) rather than
left out, so the service never sends a correction from a partial model. The tests check every effect of
the library against the model.

Static torque. Backlash, nonlinear stiffness and hysteresis act at the joint's total torque: the
static torque tau_s(q) of the arm's weight (the model's robot), its balancer and the payload (the
``gravity`` section, `carry`), plus the external tau_i. `kinematics` forms tau_s at each change of q
(one pinocchio gravity pass) and f(tau_s) of every axial term; a cycle then adds
f(tau_s + tau_i) - f(tau_s), loaded minus unloaded as the campaign measured it. A robot without masses
carrying nothing has tau_s = 0 and pays nothing.

History. A history term (hysteresis' loading state) keeps its state in this predictor;
`reset_history` restarts it at its defined start. The compensator calls it at the first sample, after a
tare and after a fault reset.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin
from pydantic import Field

from stiffness.errors import StiffnessError, quote
from stiffness.files.yaml_schema import Strict
from stiffness.kinematics.robot import BODIES
from stiffness.kinematics.spatial import damped_pinv_solve
from stiffness.kinematics.statics import PayloadConfig, statics_for
from stiffness.model.stiffness_model import StiffnessModel

from .errors import ServiceConfigError
from .fast_effects import fast_terms

_BASE = np.eye(4)


class ModelConfig(Strict):
    """``model``: the model file (relative to the config file) and how the correction is solved."""

    file: str
    refinement_iterations: int = Field(0, ge=0, le=10)
    damping: float = Field(1e-3, ge=0.0, le=1.0)


def load_model(cfg) -> StiffnessModel:
    """The model ``model.file`` of the service config ``cfg`` names, physical (no negative compliance);
    ServiceConfigError names the config file, the key and its value, then what is wrong."""
    try:
        model = StiffnessModel.from_yaml(cfg.resolve(cfg.model.file))
        model.require_physical()
    except StiffnessError as e:
        raise ServiceConfigError(f"{cfg.path}: model.file = {quote(cfg.model.file)}: {e}") from e
    return model


class FastPredictor:
    """Per-cycle deflection and δq for a model made of supported effects.

    Call `kinematics(q)` when q changes (it also forms the damped pseudo-inverse), then
    `wrench_base`, `deflection` and `correction` every cycle.

    Parameters
    ----------
    model : StiffnessModel
    damping : float
        λ of the damped pseudo-inverse (m or rad scale; 1e-3 is invisible away from singularities).
    refinement_iterations : int
        Newton steps on the full kinematics after the first linear step.
    """

    def __init__(self, model: StiffnessModel, damping: float = 1e-3, refinement_iterations: int = 0,
                 dynamics: list | None = None):
        terms = fast_terms(model, dynamics)
        self.compliance = terms.compliance       # (frame, [x y z rx ry rz]); frame k holds joint k+1's spring
        self.axial = terms.axial
        self.statics = model.statics()
        self.preloads = model.preloads()         # identified static torque (stiffness.model.preload_term), kept by carry
        self._q: np.ndarray | None = None        # the joints of the last kinematics (rad)
        self.tau_s = [0.0] * 6                   # Nm, at the last kinematics
        self._axial_at_rest = [0.0] * len(self.axial)   # f(tau_s) of each axial term
        self.history = terms.history
        self.wrench_terms = terms.wrench_terms
        self.twist_terms = terms.twist_terms
        self.frame_terms = terms.frame_terms
        self.slow_frame_terms = [b for b in self.frame_terms if not b.constant]
        self.R_in = terms.input_rotation
        self.ignored = terms.ignored
        self.robot = model.robot
        self.pm = model.robot.pin_model
        self.pd = self.pm.createData()
        self.frame_ids = [self.pm.getFrameId(b) for b in BODIES[:6]]   # DH frames 1 .. 6
        self.tcp_id = self.pm.getFrameId("TCP")
        self.sensor_id = self.pm.getFrameId("sensor")
        self.lam = float(damping)
        self.iterations = int(refinement_iterations)
        self.Ad = np.empty((6, 6, 6))
        self.Ad[0] = np.eye(6)                  # joint 1's spring sits in the base frame
        self._w = np.empty(6)
        self.J = np.zeros((6, 6))
        self.J_pinv = np.zeros((6, 6))
        self.R_s = np.eye(3).tolist()
        self.p_s = [0.0, 0.0, 0.0]
        self.T_tcp = np.eye(4)
        self.p_tcp = [0.0, 0.0, 0.0]
        self.kernel = None                       # the compiled form (`compile`), None: the Python path

    def compile(self) -> None:
        """Run on the compiled path from now on (`service.kernel`; numba compiles or loads from its disk
        cache here, never in a cycle). Raises `service.kernel.NotCompilable` when the model has no
        compiled form; the predictor then stays on the Python path, unchanged."""
        from .kernel import CompiledPredictor

        k = CompiledPredictor(self)
        q = np.zeros(6) if self._q is None else np.asarray(self._q, dtype=float)
        k.kinematics(q)                          # the first call compiles or loads: not in a cycle
        k.predict(0.0)
        self.kernel = k
        self.reset_history()                     # the warm-up call fed the history states
        self.Ad, self.J, self.J_pinv, self.T_tcp = k.Ad, k.J, k.Jp, k.Ttcp
        self.R_s, self.p_s, self.p_tcp, self.tau_s = k.Rs, k.ps, k.Ttcp[:3, 3], k.tau_s
        self._q = q
        self.kinematics(q)

    @classmethod
    def from_config(cls, section: ModelConfig, model: StiffnessModel, dynamics=None) -> FastPredictor:
        """``dynamics``: a `service.dynamics.Dynamics` whose parts add their terms (fresh ones) to the model's."""
        return cls(model, section.damping, section.refinement_iterations,
                   dynamics.terms() if dynamics is not None else None)

    # -- per cycle ------------------------------------------------------------------------------
    def kinematics(self, q_rad: np.ndarray) -> None:
        """Frames, adjoints and the TCP Jacobian at ``q_rad`` (one pinocchio pass, or one compiled call)."""
        if self.kernel is not None:
            self._q = q_rad
            self.kernel.kinematics(q_rad)
            return
        self._q = q_rad
        pm, pd = self.pm, self.pd
        pin.computeJointJacobians(pm, pd, q_rad)
        pin.updateFramePlacements(pm, pd)
        self.J = J = pin.getFrameJacobian(pm, pd, self.tcp_id, pin.LOCAL_WORLD_ALIGNED)
        self.J_pinv = damped_pinv_solve(J, self.lam)
        oMf, Ad = pd.oMf, self.Ad
        for k in range(5):                       # the springs of joints 2..6 sit in DH frames 1..5
            Ad[k + 1] = oMf[self.frame_ids[k]].action
        if self.slow_frame_terms:                # e.g. a beam that changes with q (none on the KR 125)
            poses = [_BASE] + [oMf[fid].homogeneous for fid in self.frame_ids]
            for b in self.slow_frame_terms:
                b.C = b.update(poses)
        Ts = oMf[self.sensor_id]
        self.R_s = (Ts.rotation @ self.R_in).tolist()   # the sensor's real axes; rows, as lists
        self.p_s = Ts.translation.tolist()
        self.T_tcp = oMf[self.tcp_id].homogeneous
        self.p_tcp = self.T_tcp[:3, 3].tolist()
        if self.statics is not None:
            self._settle()

    def moved_to(self, q_rad: np.ndarray) -> None:
        """The joints (rad) whose kinematics the compiled cycle's next call forms (`service.kernel`: one call
        for the cycle, the kinematics in it); compiled only."""
        self._q = q_rad

    def _settle(self) -> None:
        """tau_s and f(tau_s) of every axial term at the last `kinematics`' joints."""
        self.tau_s = tau_s = self.statics.total_at(self._q).tolist()
        self._axial_at_rest = [term.f(tau_s[term.joint - 1]) for term in self.axial]

    def carry(self, payload_kg: float, cog_m, g_mps2) -> None:
        """The payload the sensor carries now (the ``gravity`` section: mass, centre of gravity in the
        sensor frame, gravity in base axes) in the static torque; takes effect at the next `kinematics`."""
        payload = PayloadConfig(mass_kg=payload_kg, cog_mm=[1000.0 * float(c) for c in cog_m])
        self.statics = statics_for(self.robot, payload, g_mps2, self.preloads)
        if self.kernel is not None:
            self.kernel.statics(self.statics)
        if self.statics is None:
            self.tau_s = [0.0] * 6
            self._axial_at_rest = [0.0] * len(self.axial)

    def carry_payload(self, mass_kg: float, mc_kgm) -> None:
        """Change the payload in the static torque at once, for the same gravity (a payload switch's
        blend, every cycle of its ramp): m (kg) and m c (kg m, sensor frame). The payload's torque is
        linear in both, so the blend of two payloads is the blend of their tau_s; `Statics.carry` moves
        it without a new pinocchio model, and tau_s is formed again at the last joints at once."""
        if self.statics is None:
            return
        self.statics.carry(mass_kg, mc_kgm)
        if self.kernel is not None:
            self.kernel.payload(self.statics)
            if self._q is not None:
                self.kernel.settle()
        elif self._q is not None:
            self._settle()

    def wrench_base(self, w_sensor) -> list[float]:
        """[F; M] in base axes, M about the sensor origin, from a wrench in sensor axes (six floats)."""
        (a, b, c), (d, e, f), (g, h, i) = self.R_s
        fx, fy, fz, mx, my, mz = w_sensor
        return [a * fx + b * fy + c * fz, d * fx + e * fy + f * fz, g * fx + h * fy + i * fz,
                a * mx + b * my + c * mz, d * mx + e * my + f * mz, g * mx + h * my + i * mz]

    def deflection(self, w_base, dt: float = 0.0) -> np.ndarray:
        """TCP deflection [dp (m), dr (rad)] in base axes for [F; M about the sensor origin] in base axes.

        Call it once per cycle, in time order (``dt``: s since the last cycle): it feeds this cycle's
        joint torques to the history states (the same torque again leaves a hysteresis state as it is)."""
        if self.kernel is not None:
            k = self.kernel
            k.wb[:] = w_base
            k.predict(dt)
            return k.dX.copy()
        fx, fy, fz, mx, my, mz = w_base
        x, y, z = self.p_s
        w = self._w
        w[:] = (fx, fy, fz, mx + y * fz - z * fy, my + z * fx - x * fz, mz + x * fy - y * fx)
        for wt in self.wrench_terms:
            wt.law(wt.state, wt.params, w, dt)
        local = w @ self.Ad                              # row i: W_i = Ad_i^T w0
        delta = local * self.compliance
        tau_s, at_rest = self.tau_s, self._axial_at_rest
        for k, term in enumerate(self.axial):
            j = term.joint - 1
            delta[j, 5] += term.f(tau_s[j] + float(local[j, 5])) - at_rest[k]
        for h in self.history:
            delta[h.joint - 1, 5] += h.gain * h.update(float(local[h.joint - 1, 5]), dt)
        for b in self.frame_terms:
            delta[b.frame] += b.C @ local[b.frame]
        vx, vy, vz, ox, oy, oz = (self.Ad @ delta[:, :, None]).sum(0)[:, 0].tolist()
        tx, ty, tz = self.p_tcp
        dX = np.array([vx + oy * tz - oz * ty, vy + oz * tx - ox * tz, vz + ox * ty - oy * tx, ox, oy, oz])
        for tt in self.twist_terms:
            tt.law(tt.state, tt.params, dX, dt)
        return dX

    def reset_history(self) -> None:
        """Restart every history term at its defined state."""
        for h in (*self.history, *self.wrench_terms, *self.twist_terms):
            h.reset()

    def correction(self, q_rad: np.ndarray, dX: np.ndarray) -> np.ndarray:
        """δq (rad) that moves the unloaded TCP by -dX (m, rad); `kinematics(q_rad)` must have run."""
        dq = -(self.J_pinv @ dX)
        if self.iterations:
            T0 = self.T_tcp
            p_target = T0[:3, 3] - dX[:3]
            R_target = pin.exp3(-dX[3:]) @ T0[:3, :3]
            pm, pd = self.pm, self.pd
            for _ in range(self.iterations):
                qk = q_rad + dq
                pin.computeJointJacobians(pm, pd, qk)
                pin.updateFramePlacements(pm, pd)
                Tk = pd.oMf[self.tcp_id]
                e = np.concatenate([p_target - Tk.translation, pin.log3(R_target @ Tk.rotation.T)])
                Jk = pin.getFrameJacobian(pm, pd, self.tcp_id, pin.LOCAL_WORLD_ALIGNED)
                dq = dq + damped_pinv_solve(Jk, self.lam, e)
            # pd now holds the frames of q + δq; nothing reads pd between cycles (kinematics() keeps
            # its own copies of J, the adjoints and the poses), so there is nothing to restore
        return dq
