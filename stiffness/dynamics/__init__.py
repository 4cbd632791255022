"""The dynamic compensation's stages: name -> class, in the order the cycle applies them (docs/dynamics.md).

Each stage is one module with its equation, its config section, its per-cycle terms and its test
(`stiffness.dynamics.base.Stage`); `modes` is the commissioning procedure that finds the structure's modes
from a recorded force and path (`stiffcomp modes`).
"""

from __future__ import annotations

from .base import DynamicsContext, Stage
from .feedforward import Feedforward
from .observer import Observer
from .predictor import Predictor
from .structure import Structure

STAGES: dict[str, type[Stage]] = {cls.name: cls for cls in (Predictor, Feedforward, Structure, Observer)}

__all__ = ["STAGES", "DynamicsContext", "Stage"]
