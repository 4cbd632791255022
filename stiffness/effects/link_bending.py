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

Diagnosis: tried on links 2 and 3 (the arm and the forearm, the long links) when the model lacks it.
Service: a `FrameCompliance` at the link's own DH frame m (see `realtime`).

Example: a 1 m beam with 1/EI = 1e-6 under 1000 N across it deflects L^3/3 F / EI = 0.33 mm.

>>> import numpy as np
>>> t = bending_twist(np.array([1.0]), np.array([[1.0, 0, 0]]), np.array([[0, 0, 1000.0]]), np.zeros((1, 3)))
>>> print(f"{t[0, 2] * 1e-6 * 1e3:.3f} mm")
0.333 mm
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pinocchio as pin

from ..data.campaign import Context
from .base import Effect, Param, read_location, read_values
from .terms import FrameCompliance

MIN_LENGTH_M = 0.1
DIAGNOSED_LINKS = (2, 3)
UNIT_FORCES = np.vstack([np.eye(3), np.zeros((3, 3))])
UNIT_MOMENTS = np.vstack([np.zeros((3, 3)), np.eye(3)])


class LinkBending(Effect):
    name = "link_bending"
    location_key = "link"
    equation = "t = c (L^3/3 F_perp + L^2/2 M_perp x u), r = c (L^2/2 u x F_perp + L M_perp), c = 1/EI"
    joints = (1, 2, 3, 4, 5)
    examples = ({"effect": "link_bending", "link": 2, "compliance_per_Nm2": 2e-7},
                {"effect": "link_bending", "link": 3, "compliance_per_Nm2": 3e-7})

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

    def realtime(self, robot) -> list[FrameCompliance]:
        """The cantilever as a compliance C (6x6) at the link's own DH frame m: delta_m += C W_m.

        The equation gives the tip twist for the tip wrench, both about the tip point; evaluated on the
        six unit wrenches it is a 6x6 compliance, which `compliance_at` moves to frame m (the twist and
        the wrench about frame m's origin, in its axes; for the TCP a twist at frame m and one at the tip
        frame are the same, both move every frame beyond). There the beam's length, direction and offset
        do not depend on q for the robots of this project (checked here on random configurations): C is
        formed once and a cycle costs one 6x6 product. Where they do depend on q, the term is not
        ``constant`` and the service forms C again at every change of q.
        """
        root, tip, frame = self.joint - 1, self.tip_frame(robot.frames(np.zeros((1, 6)))[0]), self.joint
        c = float(self.theta[0])

        def at(poses) -> np.ndarray:
            return c * compliance_at(poses[root], poses[tip], poses[frame])

        rng = np.random.default_rng(0)
        lim = np.radians(robot.limits_deg)
        Cs = [at(F) for F in robot.frames(np.vstack([np.zeros(6), rng.uniform(lim[:, 0], lim[:, 1], size=(3, 6))]))]
        constant = all(np.allclose(C, Cs[0], rtol=0.0, atol=1e-9 * np.abs(Cs[0]).max()) for C in Cs)
        return [FrameCompliance(frame, Cs[0], at, constant)]

    @classmethod
    def candidates(cls, model, ctx) -> list[list[LinkBending]]:
        return [[cls(link)] for link in DIAGNOSED_LINKS if not model.has(cls.name, link)]

    def size_text(self, estimate, std_error, model) -> str:
        if estimate[0] > 0:
            return f"bending stiffness EI = {1 / estimate[0]:.3g} N m² (1/EI = {estimate[0]:.3g} ± {std_error[0]:.2g})"
        return f"1/EI = {estimate[0]:.3g} ± {std_error[0]:.2g} (not a physical, positive compliance)"


def compliance_at(root: np.ndarray, tip: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """The beam's compliance per unit 1/EI (6x6) at ``frame``, from the base poses (4, 4) of the beam's
    ends and of that frame."""
    R = frame[:3, :3]
    at_tip = tip.copy()
    at_tip[:3, :3] = R                          # the tip point, in the frame's axes
    L, u = beam(root[None], at_tip[None])
    if L[0] < 1e-9:
        return np.zeros((6, 6))                 # a link of no length does not bend
    C_tip = bending_twist(np.repeat(L, 6), np.repeat(u, 6, axis=0), UNIT_FORCES, UNIT_MOMENTS).T
    T = pin.SE3(np.eye(3), R.T @ (tip[:3, 3] - frame[:3, 3])).action   # tip point -> the frame's origin
    return T @ C_tip @ T.T


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
