"""The assembly of the service's fast path (`service.compensation.FastPredictor`) from the model's effects.

Each effect returns its own real-time terms (``Effect.realtime``, the kinds in
`stiffness.effects.terms`), built from its own equation with its parameters frozen at start-up;
this module only sorts them by kind, so no equation and no effect's name is written here. An effect
with no term stops the start (`ModelUnsupportedError`), so the service never sends a correction from
a partial model. With W_k = Ad_k^T w0 the wrench at DH frame k (Eq. 4):

JointCompliance   summed into the diagonal compliances: delta_k += C_k W_k (Eq. 1, 5), k = i - 1
AxialTerm         delta_rz,k += law(tau_i, p)
HistoryTerm       delta_rz,k += gain * law(state, p, tau_i, dt), the state fed tau_i every cycle; it lives in
                  the term and restarts at the first sample, after a tare and after a fault reset
WrenchTerm        law(state, p, w0, dt): the external wrench, changed in place before the springs
TwistTerm         law(state, p, dX, dt): the TCP deflection, changed in place before the correction
FrameCompliance   delta_m += C W_m (6x6), formed again at each change of q when not constant
InputTerm         every input effect together: `StiffnessModel.input_map()` must be one rotation R of
                  force and moment; it is folded into the sensor's rotation, R_s <- R_s R, so the wrench
                  in base axes and the gravity compensation both use the sensor's real axes
Ignored           left out, its reason logged once at start-up
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

import numpy as np

from stiffness.effects.terms import (
    AxialTerm,
    FrameCompliance,
    HistoryTerm,
    Ignored,
    InputTerm,
    JointCompliance,
    TwistTerm,
    WrenchTerm,
)
from stiffness.model.stiffness_model import StiffnessModel

from .errors import ModelUnsupportedError

log = logging.getLogger("stiffcomp.service")


@dataclass
class FastTerms:
    """What the model's effects contribute to the fast path, frozen at start-up."""

    compliance: np.ndarray = field(default_factory=lambda: np.zeros((6, 6)))   # DH frame 0..5, [x .. rz]
    axial: list[AxialTerm] = field(default_factory=list)
    history: list[HistoryTerm] = field(default_factory=list)
    wrench_terms: list[WrenchTerm] = field(default_factory=list)
    twist_terms: list[TwistTerm] = field(default_factory=list)
    frame_terms: list[FrameCompliance] = field(default_factory=list)
    input_rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    ignored: list[str] = field(default_factory=list)


def input_rotation(model: StiffnessModel) -> np.ndarray:
    """R (3, 3) with W_true = blockdiag(R, R) W_measured, from the model's input effects."""
    L = model.input_map()
    R = L[:3, :3]
    if not (np.allclose(L[3:, 3:], R, atol=1e-12) and not L[:3, 3:].any() and not L[3:, :3].any()
            and np.allclose(R @ R.T, np.eye(3), atol=1e-9)):
        raise ModelUnsupportedError(f"{model.source}: the input effects do not turn the wrench by one rotation; "
                                    "the real-time predictor folds them into the sensor's rotation")
    return R


def fast_terms(model: StiffnessModel, extra: list | None = None) -> FastTerms:
    """Every effect of ``model`` as fast-path terms, then the ``extra`` terms (the dynamic compensation's,
    `service.dynamics`); refuses a model with an effect that has none."""
    terms = FastTerms()
    sources = [(e.label, e.realtime(model.robot)) for e in model.effects]
    if extra:
        sources.append(("dynamics", list(extra)))
    for label, parts in sources:
        if parts is None:
            raise ModelUnsupportedError(
                f"{model.source}: effect {label} is not supported by the real-time predictor (it has no "
                "real-time term, `Effect.realtime`); the service refuses to start rather than send a "
                "correction that leaves it out")
        for t in parts:
            if isinstance(t, JointCompliance):
                terms.compliance[t.joint - 1] += t.diagonal
            elif isinstance(t, AxialTerm):
                terms.axial.append(t)
            elif isinstance(t, HistoryTerm):
                terms.history.append(t)
            elif isinstance(t, WrenchTerm):
                terms.wrench_terms.append(t)
            elif isinstance(t, TwistTerm):
                terms.twist_terms.append(t)
            elif isinstance(t, FrameCompliance):
                terms.frame_terms.append(t)
            elif isinstance(t, Ignored):
                terms.ignored.append(t.label)
                log.warning("%s: %s ignored by the service: %s", model.source, t.label, t.reason)
            elif not isinstance(t, InputTerm):
                raise ModelUnsupportedError(f"{model.source}: effect {label} returned {type(t).__name__}, "
                                            "which is not a real-time term (stiffness.effects.terms)")
    terms.input_rotation = input_rotation(model)
    return terms
