"""The dynamic compensation's parts: name -> class, in the order the cycle applies them (docs/dynamics.md).

Each part is one module with its equation, its config section, its per-cycle terms and its test
(`stiffness.dynamics.base.Part`); `identify` is the commissioning procedure that finds the structure's modes
from a recorded force and path (`stiffcomp modes`).
"""

from __future__ import annotations

from .base import DynamicsContext, Part
from .feedforward import Feedforward
from .predictor import Predictor
from .structure import Structure

PARTS: dict[str, type[Part]] = {cls.name: cls for cls in (Predictor, Feedforward, Structure)}

__all__ = ["PARTS", "DynamicsContext", "Part"]
