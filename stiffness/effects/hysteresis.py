"""Hysteresis: an axial offset that follows the loading direction, switching smoothly (Dahl).

Equation (joint i, twist at DH frame i-1, added to rz):

    delta_rz = h * z_i

h      offset (YAML: offset_deg, deg); friction in the gearbox makes the deflection lag the load,
       which is h < 0 with this sign convention
z_i    the loading state in [-1, 1], a first-order (Dahl-type) law in the torque:

           dz/dtau = (sgn(dtau) - z) / tau_t

       along a monotone stretch of the torque, so a move of the torque by Delta takes z to

           z <- s + (z - s) exp(-|Delta| / tau_t),   s = sgn(Delta)

       tau_t is the transition torque (YAML: transition_Nm, Nm, fitted by least squares, >= 0): after
       the torque reverses, the deflection has moved 63 % of the way to the other branch once the
       torque has moved by tau_t. tau_t = 0 is the instant switch, z = s.
Noise:  a reversal counts once the torque has moved back by more than threshold_Nm (YAML, fixed,
       default 10 Nm) from where it last turned; moves on in the same direction count at once. Chatter
       below the threshold leaves z alone (Dahl's law alone would walk z to 0 on noise). The default
       sits above the ripple of the torque the service computes while milling (what its low-pass
       leaves of the tooth passing, times a lever of up to 2 m: a few Nm) and far below a campaign's
       load steps (tens to hundreds of Nm).
Start:  z = 0 (the middle of the two branches: the history is unknown) with the first torque as the
       reference. Offline the state starts at each configuration's first reading and carries across
       its load sequences in time order; the service starts it at start-up, after a tare and after a
       fault reset (docs/service.md).

`loading_law` is the one implementation of the law; the model's basis (through `LoadingState`) and the
service's real-time term (a `HistoryTerm`: delta_rz = h z, the state fed tau_i every cycle, on the
Python and the compiled path) all run it.

Diagnosis: tried at every joint that has none, with tau_t fixed at 0, 3 % and 10 % of the joint's
largest torque in the campaign.

Example: a torque that rises, falls back by less than the threshold (noise), then reverses.

>>> state = LoadingState(threshold_Nm=10.0, transition_Nm=0.0)
>>> [state.update(tau) for tau in (0.0, 50.0, 45.0, 20.0)]
[0.0, 1.0, 1.0, -1.0]
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..context import Context
from ..errors import ConfigError, quote
from ..units import RAD_TO_DEG
from .axial import axial_basis, joint_torque, torque_range
from .base import Effect, Param, read_location, read_values
from .realtime import HistoryTerm

DEFAULT_THRESHOLD_NM = 10.0
DEFAULT_TRANSITION_NM = 20.0


def loading_law(s, p, tau):
    """The loading state's law, one torque in time order: updates s in place and returns z.

    s = [z, reference torque (Nm), direction (-1, 0, 1), started (0 or 1)], p = [threshold (Nm),
    transition tau_t (Nm)]. The one implementation of the module's equation: `LoadingState`, the
    model's basis and the service's `HistoryTerm` (Python and compiled) all run it.
    """
    if s[3] == 0.0:
        s[1] = tau
        s[3] = 1.0
        return s[0]
    delta = tau - s[1]
    if delta * s[2] > 0.0 or abs(delta) > p[0]:
        sign = 1.0 if delta > 0.0 else -1.0
        if p[1] > 0.0:
            s[0] = sign + (s[0] - sign) * math.exp(-abs(delta) / p[1])
        else:
            s[0] = sign
        s[2] = sign
        s[1] = tau
    return s[0]


START = (0.0, 0.0, 0.0, 0.0)       # z = 0, no reference yet


class LoadingState:
    """The loading state z of one joint, updated torque by torque (in time order), by `loading_law`.

    Parameters
    ----------
    threshold_Nm : float
        A reversal smaller than this is noise.
    transition_Nm : float
        Dahl's transition torque tau_t (0: the instant switch).
    """

    __slots__ = ("p", "s")

    def __init__(self, threshold_Nm: float, transition_Nm: float):
        self.p = [float(threshold_Nm), float(transition_Nm)]     # lists: Python floats are faster here
        self.s = list(START)

    def reset(self) -> None:
        """The defined start: z = 0, the next torque becomes the reference."""
        self.s[:] = START

    def update(self, tau: float) -> float:
        """Take the next torque (Nm); returns z."""
        return float(loading_law(self.s, self.p, float(tau)))

    @property
    def z(self) -> float:
        return float(self.s[0])

    @property
    def ref(self) -> float | None:
        """The torque the last move is measured from (Nm); None before the first torque."""
        return float(self.s[1]) if self.s[3] else None


def loading_state(ctx: Context, tau: np.ndarray, threshold_Nm: float, transition_Nm: float) -> np.ndarray:
    """z (R,) in [-1, 1] for every reading, the law run in time order within each configuration."""
    z = np.zeros(len(tau))
    state = LoadingState(threshold_Nm, transition_Nm)
    for c in range(len(ctx.config_labels)):
        idx = np.nonzero(ctx.config == c)[0]
        state.reset()
        for n in idx[np.argsort(ctx.time[idx], kind="stable")]:
            z[n] = state.update(float(tau[n]))
    return z


class Hysteresis(Effect):
    name = "hysteresis"
    equation = "delta_rz,i = h z_i, dz/dtau = (sgn(dtau) - z) / tau_t"
    evidence_plot = "axial_branches"
    examples = ({"effect": "hysteresis", "joint": 2, "offset_deg": -0.004, "transition_Nm": 40.0},)

    def __init__(self, joint: int, offset_rad: float = 0.0, transition_Nm: float = DEFAULT_TRANSITION_NM,
                 threshold_Nm: float = DEFAULT_THRESHOLD_NM, fit_transition: bool = True):
        params = [Param("offset_deg", "deg", 1e-4, yaml_factor=RAD_TO_DEG)]
        theta = [offset_rad]
        if fit_transition:
            params.append(Param("transition_Nm", "Nm", 10.0, nonlinear=True, bounds=(0.0, 1e4)))
            theta.append(transition_Nm)
        super().__init__(params, np.array(theta, dtype=float), joint)
        self.fixed_transition = None if fit_transition else float(transition_Nm)
        self.threshold_Nm = float(threshold_Nm)

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> Hysteresis:
        joint = read_location(section, "joint", cls.joints, where)
        if "threshold_fraction" in section:
            raise ConfigError(f"{where}: threshold_fraction is no longer read: the threshold is a torque, "
                              f"threshold_Nm (default {DEFAULT_THRESHOLD_NM:g} Nm), the same offline and in "
                              "the service; replace it and fit again")
        thr = section.get("threshold_Nm", DEFAULT_THRESHOLD_NM)
        if isinstance(thr, bool) or not isinstance(thr, (int, float)) or not 0 <= thr < 1e4:
            raise ConfigError(f"{where}: threshold_Nm = {quote(thr)} must be a number in [0, 1e4) Nm")
        section = {"transition_Nm": DEFAULT_TRANSITION_NM, **section}
        theta = read_values(cls.name, section, cls(joint).params, where, ("joint", "threshold_Nm"))
        return cls(joint, theta[0], theta[1], float(thr))

    def to_config(self) -> dict[str, Any]:
        out = super().to_config()
        if self.fixed_transition is not None:
            out["transition_Nm"] = float(f"{self.fixed_transition:.6g}")
        out["threshold_Nm"] = self.threshold_Nm
        return out

    def transition(self, theta: np.ndarray) -> float:
        return self.fixed_transition if self.fixed_transition is not None else float(theta[1])

    def state(self, theta: np.ndarray | None = None) -> LoadingState:
        """A fresh loading state with this effect's threshold and (frozen) transition torque."""
        return LoadingState(self.threshold_Nm, self.transition(self.theta if theta is None else theta))

    def loading(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """z (R,) of this joint for the frame wrenches W."""
        key = ("loading_state", self.joint, self.threshold_Nm, self.transition(theta))
        if W is ctx.frame_wrench and key in ctx.cache:
            return ctx.cache[key]
        z = loading_state(ctx, joint_torque(W, self.joint), self.threshold_Nm, self.transition(theta))
        if W is ctx.frame_wrench:
            ctx.cache[key] = z
        return z

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        return axial_basis(ctx, self.joint, [self.loading(ctx, W, theta)])

    def realtime(self, robot) -> list[HistoryTerm]:
        return [HistoryTerm(loading_law, [self.threshold_Nm, self.transition(self.theta)], START,
                            joint=self.joint, gain=float(self.theta[0]))]

    @classmethod
    def candidates(cls, model, ctx) -> list[list[Hysteresis]]:
        return [[cls(j, 0.0, w * torque_range(ctx, j), fit_transition=False) for w in (0.0, 0.03, 0.1)]
                for j in cls.joints if not model.has(cls.name, j)]

    def size_text(self, estimate, std_error, model) -> str:
        tau_t = self.transition(estimate)
        smooth = f", moving between branches over {tau_t:.0f} Nm" if tau_t else ", switching at once"
        return (f"offset {estimate[0] * RAD_TO_DEG:+.4f} deg (± {std_error[0] * RAD_TO_DEG:.4f}) by the direction "
                f"the torque last moved{smooth}")
