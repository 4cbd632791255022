"""The linear joint spring (the paper's 36-parameter model) and its off-axis augmentation.

Equation (Eq. 1, 4, 5): joint i's spring sits in DH frame i-1 (origin on joint i's axis); its twist

    delta_i = [x, y, z, rx, ry, rz] = C_i W_i,    C_i = diag(c_x, c_y, c_z, c_rx, c_ry, c_rz)

with W_i the external wrench about frame i-1's origin in frame i-1's axes (Eq. 4, unloaded
geometry). Units: c_x, c_y, c_z in m/N; c_rx, c_ry, c_rz in rad/Nm. rz is the axial compliance of
the joint (its gearbox and drive); the others are the bearings' tilt and translational compliance.

`joint_spring` may hold any subset of the six components (``rz`` alone is the classic axial joint
stiffness model). `joint_6dof` is the library effect that adds the five off-axis components to a
joint that has only the axial one.

Diagnosis: `joint_6dof` is tried at every joint whose spring lacks off-axis components. Service: a
`JointCompliance`, the diagonal C_i.

Example: an axial spring of 2e-7 rad/Nm under 1000 Nm about the joint's axis turns it by 2e-4 rad.

>>> s = JointSpring(joint=2, components=("rz",), theta=np.array([2e-7]))
>>> term, = s.realtime(robot=None)
>>> print(f"{term.diagonal @ np.array([0, 0, 0, 0, 0, 1000.0]):.3g} rad")
0.0002 rad
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..data.campaign import Context
from ..errors import ConfigError
from .base import Effect, Param, read_location, read_values
from .terms import JointCompliance

COMPONENTS = ("x", "y", "z", "rx", "ry", "rz")


def spring_param(component: str) -> Param:
    if component in ("x", "y", "z"):
        return Param(f"{component}_m_per_N", "m/N", 1e-9, compliance=True)
    return Param(f"{component}_rad_per_Nm", "rad/Nm", 1e-7, compliance=True)


class JointSpring(Effect):
    name = "joint_spring"
    equation = "delta_i = C_i W_i  (Eq. 1, 5); C_i diagonal, in DH frame i-1"
    default_components: tuple[str, ...] = ("rz",)

    def __init__(self, joint: int, components: tuple[str, ...], theta: np.ndarray | None = None):
        self.components = tuple(c for c in COMPONENTS if c in components)
        params = [spring_param(c) for c in self.components]
        super().__init__(params, np.zeros(len(params)) if theta is None else theta, joint)

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> JointSpring:
        joint = read_location(section, "joint", cls.joints, where)
        allowed = cls.allowed_components()
        keys = {spring_param(c).key: c for c in allowed}
        comps = tuple(keys[k] for k in section if k in keys) or cls.default_components
        params = [spring_param(c) for c in COMPONENTS if c in comps]
        theta = read_values(cls.name, section, [spring_param(c) for c in allowed], where, ("joint",))
        if not params:
            raise ConfigError(f"{where}: a {cls.name} needs at least one of {', '.join(keys)}")
        sel = [allowed.index(c) for c in COMPONENTS if c in comps]
        return cls(joint, comps, theta[sel])

    @classmethod
    def allowed_components(cls) -> tuple[str, ...]:
        return COMPONENTS

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        B = self.zeros(ctx, len(self.components))
        site = self.joint - 1
        for p, c in enumerate(self.components):
            k = COMPONENTS.index(c)
            B[:, p, site, k] = W[:, site, k]
        return B

    def realtime(self, robot) -> list[JointCompliance]:
        diagonal = np.zeros(6)
        for c, theta in zip(self.components, self.theta):
            diagonal[COMPONENTS.index(c)] = theta
        return [JointCompliance(self.joint, diagonal)]


def axial_compliance(model, joint: int) -> float | None:
    """Joint ``joint``'s axial compliance c_rz in ``model`` (rad/Nm), None when it has none."""
    for e in model.effects:
        if isinstance(e, JointSpring) and e.joint == joint and "rz" in e.components:
            return float(e.theta[e.components.index("rz")])
    return None


class Joint6Dof(JointSpring):
    name = "joint_6dof"
    equation = ("delta_i += diag(c_x, c_y, c_z, c_rx, c_ry, 0) W_i  (Eq. 5): the off-axis and "
                "translational springs of joint i added to its axial spring")
    default_components = ("x", "y", "z", "rx", "ry")

    @classmethod
    def allowed_components(cls) -> tuple[str, ...]:
        return ("x", "y", "z", "rx", "ry")

    @classmethod
    def candidates(cls, model, ctx) -> list[list[Joint6Dof]]:
        springs: dict[int, set[str]] = {}
        for e in model.effects:
            if isinstance(e, JointSpring):
                springs.setdefault(e.joint, set()).update(e.components)
        out = []
        for j, have in sorted(springs.items()):
            missing = tuple(c for c in cls.allowed_components() if c not in have)
            if missing:
                out.append([cls(j, missing)])
        return out

    def size_text(self, estimate, std_error, model) -> str:
        parts = [f"{comp} {1 / val:.3g} {'N/m' if comp in 'xyz' else 'Nm/rad'}"
                 for comp, val, s in zip(self.components, estimate, std_error) if val > 3 * s]
        return "stiffness " + (", ".join(parts) if parts else "below the noise in every direction")
