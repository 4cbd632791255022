"""The answer each interface expects, from the newest joint correction: AK or RKorr, planned joints or a path
correction; and the joints the cycle uses, from what the packet gives.

The Cartesian answers (RSI's RKorr, EGM's path correction) carry the TCP motion the joint correction makes at
the programmed joints, J(q) dq: so they hold the cycle's limits and ramps as the joint answer does.
"""

from __future__ import annotations

from collections import deque

import numpy as np

from .packets import RobotPacket
from .settings import RobotSettings

ZERO6 = (0.0,) * 6
HISTORY = 64                    # answers remembered for a robot that reports it missed some (RSI's Delay)


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


class Answerer:
    """Reads the interface's packets and writes its answers, keeping what the robot holds of the correction.

    Parameters
    ----------
    settings : RobotSettings
    robot_file : the robot's YAML (the model's robot), needed for a Cartesian answer
    """

    def __init__(self, settings: RobotSettings, robot_file: str | None = None):
        self.s = settings
        self.kind = settings.interface
        if self.kind == "kuka_rsi":
            from . import rsi

            self.codec = rsi
            self.stamp_step = settings.kuka_rsi.cycle_ms           # IPOC counts milliseconds
        else:
            from . import egm

            self.codec = egm
            self.stamp_step = 1                                    # EGM's seqno counts packets
        self.jacobian = None
        if settings.cartesian:
            from stiffness.kinematics.robot import load_robot

            if robot_file is None:
                raise ValueError("a Cartesian answer needs the robot's kinematics (the model's robot file)")
            self.jacobian = TcpJacobian(load_robot(robot_file))
        self.seqno = 0                  # EGM: the sensor's own rising count
        self.restart()

    def restart(self) -> None:
        """A new session: the robot holds no correction, and the path's last pose is forgotten."""
        # RSI, after each answer, newest last: (the joint correction behind it, the total of the relative
        # increments sent); what the robot holds is the newest, or an older one if it missed the newest
        self.history: deque[tuple[list[float], list[float]]] = deque([(list(ZERO6), list(ZERO6))], maxlen=HISTORY)
        self.last_pose = self.last_x = None      # EGM path: the last planned pose and path frame's x

    def missed(self, n: int) -> None:
        """The robot says (RSI's ``Delay`` rose by ``n``) that it did not take the last ``n`` answers: it holds
        what it held before them."""
        for _ in range(min(n, len(self.history) - 1)):
            self.history.pop()

    def parse(self, data: bytes) -> RobotPacket:
        if self.kind == "kuka_rsi":
            return self.codec.parse(data, self.s.kuka_rsi)
        return self.codec.parse(data)

    def programmed(self, joints_deg, new_session: bool = False, missed: int = 0) -> list[float]:
        """The programmed joints: RSI's setpoints less the correction the robot holds, when they include it (at
        a session's first packet the robot holds none; having ``missed`` the last answers, what it held before)."""
        if self.kind == "kuka_rsi" and self.s.kuka_rsi.joints_include_correction and not new_session:
            held = self.history[-1 - min(missed, len(self.history) - 1)][0]
            return [q - h for q, h in zip(joints_deg, held)]
        return list(joints_deg)

    def answer(self, p: RobotPacket, q: list[float], correction: list[float], age_ms: float) -> bytes:
        """The answer to packet ``p`` whose programmed joints are ``q``, for the joint ``correction`` (deg). It
        names its packet as the robot's interface lets it: RSI's IPOC repeated; EGM's header tm set to the
        packet's tm (the sensor's own rising seqno beside it), so the robot can tell its round trip."""
        if self.kind == "kuka_rsi":
            k = self.s.kuka_rsi
            if k.cartesian:
                m = self.jacobian.motion(q, correction)
                values = [*m[:3], m[5], m[4], m[3]]        # RKorr A, B, C turn about Z, Y, X
            else:
                values = correction
            sent = list(values)                 # the total the robot holds once it takes this answer
            if k.correction == "relative":
                values = [v - s for v, s in zip(values, self.history[-1][1])]
            self.history.append((list(correction), sent))
            return self.codec.answer(k.sen_type, p.stamp, values, k.cartesian)
        self.seqno += 1
        if self.s.abb_egm.mode == "joint":
            return self.codec.joint_answer(self.seqno, [a + b for a, b in zip(p.joints_deg, correction)], p.tm_ms)
        d = self.jacobian.motion(q, correction)[:3]
        if p.pose is None:
            raise ValueError("an EGM path correction needs the planned pose in the robot's packet")
        frame = self.codec.path_frame(self.last_pose or p.pose, p.pose, self.last_x)
        self.last_pose, self.last_x = p.pose, frame[0]
        return self.codec.path_answer(self.seqno, self.codec.to_path(frame, d), round(max(age_ms, 0.0)), p.tm_ms)
