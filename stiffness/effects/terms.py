"""The terms an effect contributes to the service's 1 ms path (`service.fast_effects` assembles them).

Each effect's ``realtime(robot)`` returns a list of these, built from its own equation with its
parameters frozen at start-up; the service knows these few kinds of term and never an effect's name.
With W_k = Ad_k^T w0 the external wrench at DH frame k (Eq. 4) and delta_k the twist there
([x, y, z, rx, ry, rz], m and rad), a term adds:

=================  =====================================================================================
JointCompliance    delta_{i-1} += diag(c) W_{i-1}: the springs of joint i (Eq. 1, 5)
AxialTerm          delta_{i-1}[rz] += law(tau_i, params), tau_i = W_{i-1}[rz]: a function of the joint's torque
HistoryTerm        delta_{i-1}[rz] += gain * law(state, params, tau_i, dt): a function of the torque's history;
                   ``law`` updates ``state`` (a float array) in place; the state restarts at ``start`` at
                   the first sample, a tare and a fault reset
WrenchTerm         law(state, params, w0, dt) changes w0 in place (the external wrench in base axes, about
                   the base origin, before the springs): a filter or predictor of the wrench
TwistTerm          law(state, params, dX, dt) changes dX in place (the TCP deflection [m, rad], base axes,
                   before the correction): a filter of the deflection, e.g. a structure's modes
FrameCompliance    delta_m += C W_m, C (6x6) at DH frame m; when it depends on q (not ``constant``),
                   ``update(poses)`` forms it again (``poses``: the base and DH frames 1..6, (4, 4) each)
InputTerm          the effect turns the sensor wrench: the service takes every input effect together
                   from `StiffnessModel.input_map` and folds the result into the sensor's rotation
Ignored            nothing is compensated; the service logs ``reason`` once at start-up
=================  =====================================================================================

The compiled form (`service.kernel`). A ``law`` is a plain numeric function written once, at module
level in the effect's own file: floats, float arrays (``params``, ``state``; indexed, never resized) and
`math`/NumPy scalar functions, so that Python runs it as it is and the service compiles it (numba) into
the 1 ms cycle. Both paths run the same function. A term built from a Python callable alone (``AxialTerm(j,
f)``), a ``FrameCompliance`` that depends on q, or a law the compiler refuses, has no compiled form: the
service then runs the whole cycle on the Python path and says so in one log line at start-up; it is never
refused for that.

An effect whose ``realtime`` returns None has no term: the service refuses a model that holds it
rather than send a correction that leaves it out.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np


@dataclass
class JointCompliance:
    joint: int
    diagonal: np.ndarray                   # (6,) m/N and rad/Nm, [x y z rx ry rz]


def _floats(a) -> np.ndarray:
    return np.ascontiguousarray(a, dtype=float).reshape(-1)


@dataclass
class AxialTerm:
    """delta_rz += f(tau): ``law(tau, params)`` (compiled form), or a Python callable ``f`` alone."""

    joint: int
    f: Callable[[float], float] | None = None      # tau_i (Nm) -> delta_rz (rad); from law and params if None
    law: Callable[[float, np.ndarray], float] | None = None
    params: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __post_init__(self):
        self.params = _floats(self.params)
        if self.f is None:
            if self.law is None:
                raise TypeError("an AxialTerm needs a law (with its params) or a callable f")
            law, p = self.law, self.params
            self.f = lambda tau: float(law(tau, p))


@dataclass
class _StatefulTerm:
    """A term with a state (float array) its law updates in place; ``reset`` restarts it at ``start``."""

    law: Callable
    params: np.ndarray
    start: np.ndarray
    state: np.ndarray = field(default=None, repr=False)     # type: ignore[assignment]

    def __post_init__(self):
        self.params = _floats(self.params)
        self.start = _floats(self.start)
        self.state = self.start.copy()

    def reset(self) -> None:
        """The defined start (in place: a compiled cycle holds a view of ``state``)."""
        self.state[:] = self.start


@dataclass
class HistoryTerm(_StatefulTerm):
    """delta_rz += gain * law(state, params, tau, dt): the joint torque's history (dt: s since the last cycle)."""

    joint: int = 0
    gain: float = 0.0                      # rad per unit of the law's value

    def update(self, tau: float, dt: float = 0.0) -> float:
        """Feed this cycle's torque (Nm), ``dt`` s after the last; returns the law's value (before the gain)."""
        return self.law(self.state, self.params, tau, dt)


@dataclass
class WrenchTerm(_StatefulTerm):
    """law(state, params, w0, dt) changes the external wrench w0 (6,) in place before the springs."""


@dataclass
class TwistTerm(_StatefulTerm):
    """law(state, params, dX, dt) changes the TCP deflection dX (6,) in place before the correction."""


@dataclass
class FrameCompliance:
    frame: int                             # DH frame m (1..6)
    C: np.ndarray                          # (6, 6)
    update: Callable[[list[np.ndarray]], np.ndarray] = field(repr=False)
    constant: bool = True                  # C does not depend on q: formed once, ``update`` never called


@dataclass(frozen=True)
class InputTerm:
    label: str


@dataclass(frozen=True)
class Ignored:
    label: str
    reason: str


Term = JointCompliance | AxialTerm | HistoryTerm | WrenchTerm | TwistTerm | FrameCompliance | InputTerm | Ignored
