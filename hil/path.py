"""The nominal circle and the joint references that follow it (the PLC's program).

The circle lies in the horizontal plane through the TCP at ``center_q_deg`` with that pose's tool
orientation; the path angle phi runs from 0 to 2 pi at constant feed:

    p(phi) = c + r (cos(phi) x + s sin(phi) y),     phi(t) = s_dir * v t / r  (s = +1 ccw, -1 cw)

Inverse kinematics: damped Newton on the full TCP pose (pinocchio), warm-started from the previous
point, solved once at ``points`` angles; the references are linear in between (the chord's sagitta
at 720 points is 0.3 µm for r = 35 mm).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from stiffness.kinematics.robot import Robot
from stiffness.kinematics.spatial import damped_pinv_solve

from .scenario import CircleConfig


class IkError(RuntimeError):
    """The inverse kinematics did not converge at a point of the path."""


def solve_ik(robot: Robot, T_target: pin.SE3, q0: np.ndarray, tol: float = 1e-10, max_iter: int = 50,
             lam: float = 1e-3) -> np.ndarray:
    """Joint angles (rad) that put the TCP at ``T_target`` (damped Newton from ``q0``, damping λ = ``lam``)."""
    pm = robot.pin_model
    pd = pm.createData()
    fid = pm.getFrameId("TCP")
    q = np.array(q0, dtype=float)
    for _ in range(max_iter):
        pin.computeJointJacobians(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        err = pin.log6(pd.oMf[fid].actInv(T_target)).vector          # local frame error
        if err @ err < tol * tol:
            return q
        J = pin.getFrameJacobian(pm, pd, fid, pin.LOCAL)
        q = q + damped_pinv_solve(J, lam, err)
    raise IkError(f"inverse kinematics did not converge (residual {np.linalg.norm(err):.2e})")


class CirclePath:
    """The circle, its timing and its joint references.

    Parameters
    ----------
    robot : Robot
    cfg : CircleConfig
    """

    def __init__(self, robot: Robot, cfg: CircleConfig):
        self.robot = robot
        self.radius = cfg.radius_mm / 1000.0
        self.feed = cfg.feed_mm_s / 1000.0
        self.sign = 1.0 if cfg.direction == "ccw" else -1.0
        self.duration = 2 * np.pi * self.radius / self.feed           # s for one circle
        self.lead_s, self.tail_s = cfg.lead_s, cfg.tail_s
        q_c = np.radians(cfg.center_q_deg)
        T_c = robot.frames(q_c[None])[0, 7]
        self.center = T_c[:3, 3].copy()
        self.R_tool = T_c[:3, :3].copy()
        self.phi = np.linspace(0.0, 2 * np.pi, cfg.points + 1)
        q = np.empty((len(self.phi), 6))
        guess = q_c
        for k, phi in enumerate(self.phi):
            try:
                guess = solve_ik(robot, pin.SE3(self.R_tool, self.point(phi)), guess)
            except IkError as e:
                raise IkError(f"{e} at {np.degrees(phi):.0f} deg along the circle") from e
            q[k] = guess
        self.q_table_deg = np.degrees(q)

    def point(self, phi: np.ndarray | float) -> np.ndarray:
        """Nominal TCP position(s) (m, base) at path angle(s) ``phi``."""
        phi = np.asarray(phi, dtype=float)
        off = np.stack([np.cos(phi), self.sign * np.sin(phi), np.zeros_like(phi)], axis=-1)
        return self.center + self.radius * off

    def angle(self, t: np.ndarray | float) -> np.ndarray:
        """Path angle (rad, 0..2 pi) at time ``t`` (s since the cut started), held at the ends."""
        return np.clip(np.asarray(t, dtype=float) / self.duration, 0.0, 1.0) * 2 * np.pi

    def tangent(self, phi: np.ndarray) -> np.ndarray:
        """Unit feed direction (base axes)."""
        phi = np.asarray(phi, dtype=float)
        return np.stack([-np.sin(phi), self.sign * np.cos(phi), np.zeros_like(phi)], axis=-1)

    def outward(self, phi: np.ndarray) -> np.ndarray:
        """Unit radial direction from the centre (base axes)."""
        phi = np.asarray(phi, dtype=float)
        return np.stack([np.cos(phi), self.sign * np.sin(phi), np.zeros_like(phi)], axis=-1)

    def q_ref_deg(self, t: float) -> list[float]:
        """Joint references (deg) at time ``t`` (s since the cut started)."""
        x = float(np.clip(t / self.duration, 0.0, 1.0)) * (len(self.phi) - 1)
        k = min(int(x), len(self.phi) - 2)
        a = x - k
        return ((1.0 - a) * self.q_table_deg[k] + a * self.q_table_deg[k + 1]).tolist()

    def radial_error(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Angle (rad) and radial error (m, + outside) of positions ``p`` (N, 3) from the circle's plane view."""
        d = np.asarray(p)[:, :2] - self.center[:2]
        return np.arctan2(self.sign * d[:, 1], d[:, 0]) % (2 * np.pi), np.hypot(d[:, 0], d[:, 1]) - self.radius
