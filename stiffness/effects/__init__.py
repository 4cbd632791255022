"""The effect library: name -> class. Each effect is one module with its equation and its tests."""

from __future__ import annotations

from .base import Effect, Param
from .joint_spring import Joint6Dof, JointSpring

EFFECTS: dict[str, type[Effect]] = {
    JointSpring.name: JointSpring,
    Joint6Dof.name: Joint6Dof,
}


def register(cls: type[Effect]) -> type[Effect]:
    EFFECTS[cls.name] = cls
    return cls


__all__ = ["EFFECTS", "Effect", "Param", "register"]
