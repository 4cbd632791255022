"""The terms an effect contributes to the service's 1 ms path (`service.fast_effects` assembles them).

Each effect's ``realtime(robot)`` returns a list of these, built from its own equation with its
parameters frozen at start-up; the service knows these few kinds of term and never an effect's name.
With W_k = Ad_k^T w0 the external wrench at DH frame k (Eq. 4) and delta_k the twist there
([x, y, z, rx, ry, rz], m and rad), a term adds:

=================  =====================================================================================
JointCompliance    delta_{i-1} += diag(c) W_{i-1}: the springs of joint i (Eq. 1, 5)
AxialTerm          delta_{i-1}[rz] += f(tau_i), tau_i = W_{i-1}[rz]: a function of the joint's torque
HistoryTerm        delta_{i-1}[rz] += gain * state.update(tau_i): a function of the torque's history;
                   the state restarts (``state.reset()``) at the first sample, a tare and a fault reset
FrameCompliance    delta_m += C W_m, C (6x6) at DH frame m; when it depends on q (not ``constant``),
                   ``update(poses)`` forms it again (``poses``: the base and DH frames 1..6, (4, 4) each)
InputTerm          the effect turns the sensor wrench: the service takes every input effect together
                   from `StiffnessModel.input_map` and folds the result into the sensor's rotation
Ignored            nothing is compensated; the service logs ``reason`` once at start-up
=================  =====================================================================================

An effect whose ``realtime`` returns None has no term: the service refuses a model that holds it
rather than send a correction that leaves it out.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np


class TorqueState(Protocol):
    """A joint's history as the cycle feeds it its torque (Nm), cycle by cycle in time order."""

    def update(self, tau: float) -> float: ...

    def reset(self) -> None: ...


@dataclass
class JointCompliance:
    joint: int
    diagonal: np.ndarray                   # (6,) m/N and rad/Nm, [x y z rx ry rz]


@dataclass
class AxialTerm:
    joint: int
    f: Callable[[float], float]            # tau_i (Nm) -> delta_rz (rad)


@dataclass
class HistoryTerm:
    joint: int
    gain: float                            # rad per unit of the state
    state: TorqueState


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


Term = JointCompliance | AxialTerm | HistoryTerm | FrameCompliance | InputTerm | Ignored
