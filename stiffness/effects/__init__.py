"""The effect library: name -> class. Each effect is one module with its equation and its tests."""

from __future__ import annotations

from .backlash import Backlash
from .base import Effect, Param
from .drift import Drift
from .hysteresis import Hysteresis
from .joint_spring import Joint6Dof, JointSpring
from .link_bending import LinkBending
from .nonlinear_stiffness import NonlinearStiffness
from .sensor_misalignment import SensorMisalignment

EFFECTS: dict[str, type[Effect]] = {cls.name: cls for cls in (
    JointSpring, Joint6Dof, Backlash, Hysteresis, NonlinearStiffness, LinkBending, SensorMisalignment, Drift,
)}

__all__ = ["EFFECTS", "Effect", "Param"]
