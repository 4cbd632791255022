"""The TCP's motion that a joint correction makes, for the answers that carry it (RSI's RKorr, EGM's path
correction): J(q) dq, so they hold the cycle's limits and ramps as a joint answer does; and RKorr's angles.
"""

from __future__ import annotations

import numpy as np


class TcpJacobian:
    """The TCP's Jacobian of a robot in the units of the answers: mm and deg of TCP motion per deg of joint
    motion, base axes (pinocchio's frame Jacobian, LOCAL_WORLD_ALIGNED; about 1 us a call)."""

    SCALE = np.array([1000.0 * np.pi / 180.0] * 3 + [1.0] * 3)[:, None]     # m/rad -> mm/deg; rad/rad stays

    def __init__(self, robot):
        import pinocchio as pin

        self._pin = pin
        self.model = robot.pin_model
        self.data = self.model.createData()
        self.frame = self.model.getFrameId("TCP")

    def __call__(self, q_deg) -> np.ndarray:
        pin = self._pin
        J = pin.computeFrameJacobian(self.model, self.data, np.radians(np.asarray(q_deg, dtype=float)), self.frame,
                                     pin.LOCAL_WORLD_ALIGNED)
        return self.SCALE * J

    def motion(self, q_deg, dq_deg) -> np.ndarray:
        """(dx, dy, dz) in mm and (rx, ry, rz) in deg: the TCP's motion in the base frame that the joint
        correction ``dq_deg`` makes at ``q_deg``, J(q) dq (to first order: 3e-5 mm off the exact motion for
        0.03 deg on a KR 125)."""
        return self(q_deg) @ np.asarray(dq_deg, dtype=float)


def rkorr(motion) -> tuple[float, ...]:
    """RSI's ``RKorr X Y Z A B C`` from a TCP motion (dx, dy, dz mm; rx, ry, rz deg about the base's x, y, z).

    A, B, C are KUKA's ZYX angles: A about Z, then B about the new Y, then C about the new X. For a small
    rotation they are the rotation vector's z, y and x components, to first order: the exact ZYX angles of the
    rotation vector r differ from (rz, ry, rx) by at most 0.0044 deg x (|r| / 1 deg)^2 (scipy's Rotation, 20,000
    random axes each: 3.9e-6 deg at |r| = 0.03 deg, a correction's size; 4.4e-5 deg at 0.1 deg, 4.4e-3 deg at
    1 deg; `tests/robot_road/test_road_packets.py` holds the bound). The robot side reads them back with
    `motion_of_rkorr`."""
    m = tuple(float(v) for v in motion)
    return (*m[:3], m[5], m[4], m[3])


def motion_of_rkorr(values) -> tuple[float, ...]:
    """The TCP motion (dx, dy, dz, rx, ry, rz) an ``RKorr X Y Z A B C`` stands for, to first order (`rkorr`)."""
    v = tuple(float(x) for x in values)
    return (*v[:3], v[5], v[4], v[3])
