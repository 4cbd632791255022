"""Hysteresis: an axial offset that follows the loading direction, switching smoothly (Dahl), with stiction.

Equation (joint i, twist at DH frame i-1, added to rz):

    delta_rz = h * z_i

h      offset (YAML: offset_deg, deg); friction in the gearbox makes the deflection lag the load,
       which is h < 0 with this sign convention
z_i    the loading state in [-1, 1]. After the torque turns at tau_r (the state there z_r) and has
       moved on from it by Delta, in the direction s = sgn(Delta):

           z = z_r                                                    |Delta| <= tau_b  (stick)
           z = s + (z_r - s) exp(-(|Delta| - tau_b) / tau_t)          |Delta| >  tau_b  (slip)

       tau_b is the breakaway torque (YAML: threshold_Nm, fixed, default 10 Nm): the contacts stick,
       and z keeps its value, until the torque has moved back that far from where it last turned; beyond
       it they slip and z follows Dahl's law dz/dtau = (s - z) / tau_t from where it stood, continuously.
       tau_t is the transition torque (YAML: transition_Nm, Nm, fitted by least squares, >= 0): z has
       moved 63 % of the way to the other branch tau_t beyond the breakaway; tau_t = 0 is the instant
       switch (a relay with the hysteresis width tau_b). Moves on in the same direction slip at once.
Input:  the torque the joint's motion follows (YAML: bandwidth_hz, fixed, default 5 Hz): tau_i through a
       critically damped low-pass at that frequency, (1 + s / w)^-2. A joint's friction slips only as the
       joint moves, and the arm's inertia keeps it from following a ripple near or above its first mode
       (about 10 Hz on a milling robot; the tooth passing, the chip load's variation): that ripple is
       taken by the arm's mass and the contacts' elastic presliding, not by slipping (docs/effects.md,
       "Hysteresis under a ripple"); the default is half that mode. Readings further apart than a few
       periods (a campaign's load steps) pass unchanged: the low-pass acts in time, on the readings' own
       time stamps (or the cycle's dt), and a reading with no time step passes as it is.
Start:  z = 0 (the middle of the two branches: the history is unknown). The contacts stick while the
       torque stays within tau_b of every torque since the start; the first move that takes it more than
       tau_b above the lowest (below the highest) turns there, so z stays continuous in the torque.
       Offline the state starts at each configuration's first reading and carries across its load
       sequences in time order; the service starts it at start-up, after a tare and after a fault reset
       (docs/service.md).

`loading_law` is the one implementation of the law; the model's basis (through `LoadingState`), the HIL's
robot stub (the truth model) and the service's real-time term (a `HistoryTerm`: delta_rz = h z, the state
fed tau_i and the cycle's dt every cycle, on the Python and the compiled path) all run it.

Diagnosis: tried at every joint that has none, with tau_t fixed at 0, 3 % and 10 % of the joint's
largest torque in the campaign.

Example: a torque that rises, falls back by less than the breakaway (noise), then reverses; smoothly, z
slips only by the move beyond the breakaway (35 Nm is 15 Nm back from the turn at 50 Nm: 5 Nm of slip).

>>> state = LoadingState(threshold_Nm=10.0, transition_Nm=0.0)
>>> [state.update(tau) for tau in (0.0, 50.0, 45.0, 20.0)]
[0.0, 1.0, 1.0, -1.0]
>>> smooth = LoadingState(threshold_Nm=10.0, transition_Nm=20.0)
>>> [round(smooth.update(tau), 3) for tau in (0.0, 50.0, 45.0, 35.0, 30.0)]
[0.0, 0.865, 0.865, 0.452, 0.131]
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..data.campaign import Context
from ..errors import ConfigError, quote
from ..units import RAD_TO_DEG
from .axial import axial_basis, joint_torque, torque_range
from .base import Effect, Param, read_location, read_values
from .terms import HistoryTerm

DEFAULT_THRESHOLD_NM = 10.0
DEFAULT_TRANSITION_NM = 20.0
DEFAULT_BANDWIDTH_HZ = 5.0       # half the first mode of a milling robot (about 10 Hz): below it the joint follows
TWO_PI = 2.0 * math.pi


def loading_law(s, p, tau, dt):
    """The loading state's law, one torque in time order: updates s in place and returns z.

    s = [z, turning torque tau_r (Nm), direction (-1, 0, 1), started (0 or 1), z at the turn z_r, the
    extreme since the turn (Nm), the low-pass's two stages (Nm)]; before the first move (direction 0)
    s[1] and s[5] hold the lowest and the highest torque since the start; p = [breakaway tau_b (Nm), transition
    tau_t (Nm), bandwidth (Hz, 0: none)]; dt the time since the last torque (s; 0: a reading without a time
    step, taken as it is). The one implementation of the module's equation: `LoadingState`, the model's
    basis, the robot stub and the service's `HistoryTerm` (Python and compiled) all run it.
    """
    if s[3] == 0.0:
        s[1] = tau
        s[4] = s[0]
        s[5] = tau
        s[6] = tau
        s[7] = tau
        s[3] = 1.0
        return s[0]
    if dt > 0.0 and p[2] > 0.0:
        a = 1.0 - math.exp(-TWO_PI * p[2] * dt)
        s[6] += a * (tau - s[6])
        s[7] += a * (s[6] - s[7])
        tau = s[7]
    else:
        s[6] = tau
        s[7] = tau
    d = s[2]
    if d == 0.0:                                     # not moved yet: s[1], s[5] the lowest, highest torque so far
        if tau - s[1] > p[0]:                        # up by more than the breakaway from the lowest: turned there
            d = 1.0
        elif s[5] - tau > p[0]:                      # down by more than the breakaway from the highest
            d = -1.0
            s[1] = s[5]
        else:                                        # stick (the range so far stays within the breakaway)
            s[1] = min(s[1], tau)
            s[5] = max(s[5], tau)
            return s[0]
        s[2] = d
        s[4] = s[0]
        s[5] = tau
    elif (tau - s[5]) * d >= 0.0:                    # on in the same direction: a new extreme
        s[5] = tau
    elif abs(tau - s[5]) > p[0]:                     # back by more than the breakaway: it turned at s[5]
        s[1] = s[5]
        s[4] = s[0]
        d = -d
        s[2] = d
        s[5] = tau
    else:                                            # stick
        return s[0]
    slip = abs(s[5] - s[1]) - p[0]
    if slip > 0.0:
        s[0] = d if p[1] <= 0.0 else d + (s[4] - d) * math.exp(-slip / p[1])
    return s[0]


START = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)       # z = 0, no turning point yet


class LoadingState:
    """The loading state z of one joint, updated torque by torque (in time order), by `loading_law`.

    Parameters
    ----------
    threshold_Nm : float
        The breakaway tau_b: a reversal smaller than this sticks.
    transition_Nm : float
        Dahl's transition torque tau_t (0: the instant switch).
    bandwidth_hz : float
        The joint follows the torque below this (Hz; 0: the torque as it is).
    """

    __slots__ = ("p", "s")

    def __init__(self, threshold_Nm: float, transition_Nm: float, bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ):
        self.p = [float(threshold_Nm), float(transition_Nm), float(bandwidth_hz)]   # lists: faster here
        self.s = list(START)

    def reset(self) -> None:
        """The defined start: z = 0, the next torque becomes the reference."""
        self.s[:] = START

    def update(self, tau: float, dt: float = 0.0) -> float:
        """Take the next torque (Nm), ``dt`` s after the last one (0: no time step); returns z."""
        return float(loading_law(self.s, self.p, float(tau), float(dt)))

    @property
    def z(self) -> float:
        return float(self.s[0])

    @property
    def ref(self) -> float | None:
        """The torque a reversal is measured from (the extreme since the last turn, Nm); None before the
        first torque."""
        return float(self.s[5]) if self.s[3] else None


def loading_state(ctx: Context, tau: np.ndarray, threshold_Nm: float, transition_Nm: float,
                  bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ) -> np.ndarray:
    """z (R,) in [-1, 1] for every reading, the law run in time order within each configuration (the
    readings' time stamps give the low-pass its steps)."""
    z = np.zeros(len(tau))
    state = LoadingState(threshold_Nm, transition_Nm, bandwidth_hz)
    for c in range(len(ctx.config_labels)):
        idx = np.nonzero(ctx.config == c)[0]
        state.reset()
        idx = idx[np.argsort(ctx.time[idx], kind="stable")]
        t_prev = None
        for n in idx:
            t = float(ctx.time[n])
            z[n] = state.update(float(tau[n]), 0.0 if t_prev is None else t - t_prev)
            t_prev = t
    return z


class Hysteresis(Effect):
    name = "hysteresis"
    equation = "delta_rz,i = h z_i, dz/dtau = (sgn(dtau) - z) / tau_t beyond the breakaway tau_b"
    evidence_plot = "axial_branches"
    examples = ({"effect": "hysteresis", "joint": 2, "offset_deg": -0.004, "transition_Nm": 40.0},)

    def __init__(self, joint: int, offset_rad: float = 0.0, transition_Nm: float = DEFAULT_TRANSITION_NM,
                 threshold_Nm: float = DEFAULT_THRESHOLD_NM, fit_transition: bool = True,
                 bandwidth_hz: float = DEFAULT_BANDWIDTH_HZ):
        params = [Param("offset_deg", "deg", 1e-4, yaml_factor=RAD_TO_DEG)]
        theta = [offset_rad]
        if fit_transition:
            params.append(Param("transition_Nm", "Nm", 10.0, nonlinear=True, bounds=(0.0, 1e4)))
            theta.append(transition_Nm)
        super().__init__(params, np.array(theta, dtype=float), joint)
        self.fixed_transition = None if fit_transition else float(transition_Nm)
        self.threshold_Nm = float(threshold_Nm)
        self.bandwidth_hz = float(bandwidth_hz)

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> Hysteresis:
        joint = read_location(section, "joint", cls.joints, where)
        if "threshold_fraction" in section:
            raise ConfigError(f"{where}: threshold_fraction is no longer read: the threshold is a torque, "
                              f"threshold_Nm (default {DEFAULT_THRESHOLD_NM:g} Nm), the same offline and in "
                              "the service; replace it and fit again")
        fixed = {key: _fixed(section, key, default, unit, where) for key, default, unit in
                 (("threshold_Nm", DEFAULT_THRESHOLD_NM, "Nm"), ("bandwidth_hz", DEFAULT_BANDWIDTH_HZ, "Hz"))}
        section = {"transition_Nm": DEFAULT_TRANSITION_NM, **section}
        theta = read_values(cls.name, section, cls(joint).params, where, ("joint", *fixed))
        return cls(joint, theta[0], theta[1], fixed["threshold_Nm"], bandwidth_hz=fixed["bandwidth_hz"])

    def to_config(self) -> dict[str, Any]:
        out = super().to_config()
        if self.fixed_transition is not None:
            out["transition_Nm"] = float(f"{self.fixed_transition:.6g}")
        out["threshold_Nm"] = self.threshold_Nm
        out["bandwidth_hz"] = self.bandwidth_hz
        return out

    def transition(self, theta: np.ndarray) -> float:
        return self.fixed_transition if self.fixed_transition is not None else float(theta[1])

    def state(self, theta: np.ndarray | None = None) -> LoadingState:
        """A fresh loading state with this effect's breakaway, (frozen) transition torque and bandwidth."""
        return LoadingState(self.threshold_Nm, self.transition(self.theta if theta is None else theta),
                            self.bandwidth_hz)

    def loading(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        """z (R,) of this joint for the frame wrenches W."""
        key = ("loading_state", self.joint, self.threshold_Nm, self.transition(theta), self.bandwidth_hz)
        if W is ctx.frame_wrench and key in ctx.cache:
            return ctx.cache[key]
        z = loading_state(ctx, joint_torque(W, self.joint), self.threshold_Nm, self.transition(theta),
                          self.bandwidth_hz)
        if W is ctx.frame_wrench:
            ctx.cache[key] = z
        return z

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        return axial_basis(ctx, self.joint, [self.loading(ctx, W, theta)])

    def realtime(self, robot) -> list[HistoryTerm]:
        return [HistoryTerm(loading_law, [self.threshold_Nm, self.transition(self.theta), self.bandwidth_hz], START,
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


def _fixed(section: dict[str, Any], key: str, default: float, unit: str, where: str) -> float:
    """A fixed (not fitted) parameter of the entry: a number in [0, 1e4)."""
    v = section.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not 0 <= v < 1e4:
        raise ConfigError(f"{where}: {key} = {quote(v)} must be a number in [0, 1e4) {unit}")
    return float(v)
