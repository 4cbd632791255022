"""Link bending: a link as a cantilever beam clamped at its proximal joint, loaded at its tip.

Equation (link m, Euler-Bernoulli cantilever, isotropic section), with the tip wrench [F, M]
(force, and moment about the tip) in the tip frame's axes, u the unit beam axis from root to tip,
F_perp and M_perp their parts perpendicular to u, and L the beam length:

    translation  t = (1/EI) * ( L^3/3 F_perp + L^2/2 (M_perp x u) )
    rotation     r = (1/EI) * ( L^2/2 (u x F_perp) + L M_perp )

1/EI   bending compliance (YAML: compliance_per_Nm2, 1/(N m^2)); the only fitted parameter.
Geometry: the root is the origin of DH frame m-1 (on joint m's axis); the tip is the origin of DH
frame m, or of frame m+1 when frame m lies within 100 mm of the root (on the KR 125, link 3's DH
length is the 45 mm elbow offset, and the forearm that bends is the 1000 mm to the wrist centre).
The twist is applied at the tip and moves the tip frame and everything beyond it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ..context import Context
from .base import Effect, Param, read_location, read_values

MIN_LENGTH_M = 0.1


class LinkBending(Effect):
    name = "link_bending"
    location_key = "link"
    equation = "t = c (L^3/3 F_perp + L^2/2 M_perp x u), r = c (L^2/2 u x F_perp + L M_perp), c = 1/EI"
    joints = (1, 2, 3, 4, 5)

    def __init__(self, link: int, compliance: float = 0.0):
        super().__init__([Param("compliance_per_Nm2", "1/(N m^2)", 1e-10, compliance=True)], np.array([compliance]), link)

    @classmethod
    def from_config(cls, section: dict[str, Any], robot: Any, where: str) -> LinkBending:
        link = read_location(section, "link", cls.joints, where)
        theta = read_values(cls.name, section, cls(link).params, where, ("link",))
        return cls(link, theta[0])

    def tip_frame(self, F: np.ndarray) -> int:
        """The DH frame of the beam's tip, from one reading's frames F (8, 4, 4)."""
        m = self.joint
        root = F[m - 1, :3, 3]
        if np.linalg.norm(F[m, :3, 3] - root) < MIN_LENGTH_M and m < 6:
            return m + 1
        return m

    def basis(self, ctx: Context, W: np.ndarray, theta: np.ndarray) -> np.ndarray:
        tip = self.tip_frame(ctx.F[0])
        L, u = beam(ctx.F[:, self.joint - 1], ctx.F[:, tip])
        B = self.zeros(ctx, 1)
        if L.max(initial=0.0) < 1e-9:
            return B                      # a link of no length does not bend
        B[:, 0, 5 + tip] = bending_twist(L, u, W[:, tip, :3], W[:, tip, 3:])
        return B


def beam(root: np.ndarray, tip: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Length L (R,) and unit axis u (R, 3) in the tip frame's axes, from the root and tip poses (R, 4, 4)."""
    axis_base = tip[:, :3, 3] - root[:, :3, 3]
    L = np.linalg.norm(axis_base, axis=1)
    u = np.einsum("rji,rj->ri", tip[:, :3, :3], axis_base / np.maximum(L, 1e-300)[:, None])
    return L, u


def bending_twist(L: np.ndarray, u: np.ndarray, f: np.ndarray, m: np.ndarray) -> np.ndarray:
    """The cantilever's tip twist [t, r] (R, 6) per unit compliance 1/EI, for tip forces f and moments m
    (R, 3) in the tip axes: the module's equation."""
    f_perp = f - np.sum(f * u, axis=1)[:, None] * u
    m_perp = m - np.sum(m * u, axis=1)[:, None] * u
    t = (L**3 / 3)[:, None] * f_perp + (L**2 / 2)[:, None] * np.cross(m_perp, u)
    r = (L**2 / 2)[:, None] * np.cross(u, f_perp) + L[:, None] * m_perp
    return np.concatenate([t, r], axis=1)
