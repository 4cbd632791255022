"""How each effect of the library enters the service's fast path (`service.compensation.FastPredictor`).

Every effect of `stiffness.effects.EFFECTS` has an entry in `FAST_EFFECTS` (a test fails for one
that has none). Each uses the effect's own equation with its parameters frozen at start-up; no
equation is written here a second time. With W_k = Ad_k^T w0 the wrench at DH frame k (Eq. 4):

joint_spring, joint_6dof      diagonal compliances: delta_k += C_k W_k (Eq. 1, 5), k = i - 1
backlash, nonlinear_stiffness `AxialTerm`: delta_rz,k += f(tau_i), f the effect's `axial_twist`
hysteresis                    `HysteresisTerm`: delta_rz,k += h z_i, z_i the effect's `LoadingState`
                              fed tau_i every cycle (the state lives in the predictor; it restarts at
                              0 at the first sample, after a tare and after a fault reset)
link_bending                  `BendingTerm`: delta_m += C_b W_m, C_b (6x6) the effect's
                              `bending_twist` on the six unit wrenches, moved to the link's own DH
                              frame m once at start-up
sensor_misalignment           an input effect: `StiffnessModel.input_map()` (each input effect's
                              equation on the unit wrenches) must be one rotation R of force and
                              moment; it is folded into the sensor's rotation, R_s <- R_s R, so the
                              wrench in base axes and the gravity compensation both use the sensor's
                              real axes
drift                         ignored, with one warning at start-up. Drift is how a campaign's
                              readings wandered over the minutes since each configuration's unloaded
                              reference (thermal growth of the arm or the metrology), not a deflection
                              under load: the service has no such reference time, and the tare it
                              does have resets what drift would measure from. Extrapolating a
                              campaign's drift rate over hours of machining would send a correction
                              that grows without bound.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import pinocchio as pin

from stiffness.effects.axial import AxialEffect
from stiffness.effects.hysteresis import Hysteresis, LoadingState
from stiffness.effects.joint_spring import COMPONENTS, JointSpring
from stiffness.effects.link_bending import LinkBending, beam, bending_twist
from stiffness.model import StiffnessModel

from .errors import ModelUnsupportedError

log = logging.getLogger("stiffcomp.service")

UNIT_FORCES = np.vstack([np.eye(3), np.zeros((3, 3))])
UNIT_MOMENTS = np.vstack([np.zeros((3, 3)), np.eye(3)])


@dataclass
class AxialTerm:
    """An extra axial twist of joint ``joint`` (1..6): ``delta_rz = f(tau)`` with tau the axial moment (Nm)."""

    joint: int
    f: Callable[[float], float]


@dataclass
class HysteresisTerm:
    """delta_rz = offset * z, z the joint's loading state, updated with every cycle's axial moment."""

    joint: int
    offset: float
    state: LoadingState


class BendingTerm:
    """A link's cantilever compliance C (6x6) at the link's own DH frame m: delta_m += C W_m.

    The effect's equation gives the tip twist for the tip wrench, both about the tip point; evaluated
    on the six unit wrenches it is a 6x6 compliance, which `compliance` moves to frame m (the twist
    and the wrench about frame m's origin, in its axes; for the TCP a twist at frame m and one at the
    tip frame are the same, both move every frame beyond). There the beam's length, direction and
    offset do not depend on q for the robots of this project (checked at start-up on random
    configurations): C is formed once and a cycle costs one 6x6 product. A robot where they do depend
    on q pays the equation at every `kinematics` (``constant`` False).
    """

    def __init__(self, effect: LinkBending, robot):
        self.effect = effect
        F0 = robot.frames(np.zeros((1, 6)))[0]
        self.root, self.tip, self.frame = effect.joint - 1, effect.tip_frame(F0), effect.joint
        rng = np.random.default_rng(0)
        lim = np.radians(robot.limits_deg)
        Fs = robot.frames(np.vstack([np.zeros(6), rng.uniform(lim[:, 0], lim[:, 1], size=(3, 6))]))
        C = [self.compliance(F[self.root], F[self.tip], F[self.frame]) for F in Fs]
        self.constant = all(np.allclose(c, C[0], rtol=0.0, atol=1e-9 * np.abs(C[0]).max()) for c in C)
        self.C = C[0]

    def compliance(self, root: np.ndarray, tip: np.ndarray, frame: np.ndarray) -> np.ndarray:
        """C (6x6) at ``frame``, from the base poses (4, 4) of the beam's ends and of frame m."""
        R = frame[:3, :3]
        at_tip = tip.copy()
        at_tip[:3, :3] = R                          # the tip point, in frame m's axes
        L, u = beam(root[None], at_tip[None])
        if L[0] < 1e-9:
            return np.zeros((6, 6))                 # a link of no length does not bend
        C_tip = self.effect.theta[0] * bending_twist(np.repeat(L, 6), np.repeat(u, 6, axis=0),
                                                     UNIT_FORCES, UNIT_MOMENTS).T
        T = pin.SE3(np.eye(3), R.T @ (tip[:3, 3] - frame[:3, 3])).action   # tip point -> frame m's origin
        return T @ C_tip @ T.T


@dataclass
class FastTerms:
    """What the model's effects contribute to the fast path, frozen at start-up."""

    compliance: np.ndarray = field(default_factory=lambda: np.zeros((6, 6)))   # DH frame 0..5, [x .. rz]
    axial: list[AxialTerm] = field(default_factory=list)
    hysteresis: list[HysteresisTerm] = field(default_factory=list)
    bending: list[BendingTerm] = field(default_factory=list)
    input_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    ignored: list[str] = field(default_factory=list)


def _springs(effect: JointSpring, terms: FastTerms, model: StiffnessModel) -> None:
    for c, theta in zip(effect.components, effect.theta):
        terms.compliance[effect.joint - 1, COMPONENTS.index(c)] += theta


def _axial(effect: AxialEffect, terms: FastTerms, model: StiffnessModel) -> None:
    theta = effect.theta.copy()
    terms.axial.append(AxialTerm(effect.joint, lambda tau: float(effect.axial_twist(tau, theta))))


def _hysteresis(effect: Hysteresis, terms: FastTerms, model: StiffnessModel) -> None:
    terms.hysteresis.append(HysteresisTerm(effect.joint, float(effect.theta[0]), effect.state()))


def _bending(effect: LinkBending, terms: FastTerms, model: StiffnessModel) -> None:
    terms.bending.append(BendingTerm(effect, model.robot))


def _input(effect, terms: FastTerms, model: StiffnessModel) -> None:
    """Input effects are taken together, from `StiffnessModel.input_map` (see `input_rotation`)."""


def _ignored(effect, terms: FastTerms, model: StiffnessModel) -> None:
    terms.ignored.append(effect.label)


# effect name -> how it enters the fast path: fn(effect, terms, model)
FAST_EFFECTS: dict[str, Callable[[object, FastTerms, StiffnessModel], None]] = {
    "joint_spring": _springs,
    "joint_6dof": _springs,
    "backlash": _axial,
    "nonlinear_stiffness": _axial,
    "hysteresis": _hysteresis,
    "link_bending": _bending,
    "sensor_misalignment": _input,
    "drift": _ignored,
}


def input_rotation(model: StiffnessModel) -> np.ndarray:
    """R (3, 3) with W_true = blockdiag(R, R) W_measured, from the model's input effects."""
    L = model.input_map()
    R = L[:3, :3]
    if not (np.allclose(L[3:, 3:], R, atol=1e-12) and not L[:3, 3:].any() and not L[3:, :3].any()
            and np.allclose(R @ R.T, np.eye(3), atol=1e-9)):
        raise ModelUnsupportedError(f"{model.source}: the input effects do not turn the wrench by one rotation; "
                                    "the real-time predictor folds them into the sensor's rotation")
    return R


def fast_terms(model: StiffnessModel) -> FastTerms:
    """Every effect of ``model`` as a fast-path term; refuses a model with an effect that has none."""
    terms = FastTerms()
    for e in model.effects:
        hook = FAST_EFFECTS.get(e.name)
        if hook is None:
            raise ModelUnsupportedError(
                f"{model.source}: effect {e.label} is not supported by the real-time predictor "
                f"(supported: {', '.join(sorted(FAST_EFFECTS))}); the service refuses to start rather "
                "than send a correction that leaves it out")
        hook(e, terms, model)
    terms.input_rotation = input_rotation(model)
    if terms.ignored:
        log.warning("%s: %s ignored by the service: drift is how a campaign's readings wandered over time "
                    "(thermal), not a deflection under load (docs/service.md)", model.source,
                    ", ".join(terms.ignored))
    return terms
