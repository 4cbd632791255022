"""The answer each interface expects, from the newest joint correction: AK or RKorr, planned joints or a path
correction; and the joints the cycle uses, from what the packet gives.

The Cartesian answers (RSI's RKorr, EGM's path correction) carry the TCP motion the joint correction makes at
the programmed joints, FK(q + dq) - FK(q): so they hold the cycle's limits and ramps as the joint answer does.
"""

from __future__ import annotations

import numpy as np

from .packets import RobotPacket
from .settings import RobotSettings

ZERO6 = (0.0,) * 6


def tcp_motion(robot, q_deg, dq_deg) -> np.ndarray:
    """(dx, dy, dz) in mm and (rx, ry, rz) in deg: the TCP's motion in the base frame when the joints of
    ``robot`` move from ``q_deg`` by ``dq_deg`` (the rotation as its small-angle vector, from R1 R0^T)."""
    q = np.radians(np.array([q_deg, np.add(q_deg, dq_deg)]))
    F = robot.frames(q)[:, 7]
    d = 1000.0 * (F[1, :3, 3] - F[0, :3, 3])
    R = F[1, :3, :3] @ F[0, :3, :3].T
    w = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    return np.concatenate([d, np.degrees(w)])


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
        self.robot = None
        if settings.cartesian:
            from stiffness.kinematics.robot import load_robot

            if robot_file is None:
                raise ValueError("a Cartesian answer needs the robot's kinematics (the model's robot file)")
            self.robot = load_robot(robot_file)
        self.seqno = 0                  # EGM: the sensor's own rising count
        self.restart()

    def restart(self) -> None:
        """A new session: the robot holds no correction, and the path's last pose is forgotten."""
        self.held = list(ZERO6)         # the joint correction behind the last answer (deg)
        self.sent = list(ZERO6)         # relative RSI: the total of the increments sent
        self.last_pose = None

    def parse(self, data: bytes) -> RobotPacket:
        if self.kind == "kuka_rsi":
            return self.codec.parse(data, self.s.kuka_rsi)
        return self.codec.parse(data)

    def programmed(self, joints_deg) -> list[float]:
        """The programmed joints: RSI's setpoints less the correction the robot holds, when they include it."""
        if self.kind == "kuka_rsi" and self.s.kuka_rsi.joints_include_correction:
            return [q - h for q, h in zip(joints_deg, self.held)]
        return list(joints_deg)

    def tcp_motion(self, q_deg: list[float], dq_deg: list[float]) -> np.ndarray:
        return tcp_motion(self.robot, q_deg, dq_deg)

    def answer(self, p: RobotPacket, q: list[float], correction: list[float], age_ms: float) -> bytes:
        """The answer to packet ``p`` whose programmed joints are ``q``, for the joint ``correction`` (deg)."""
        self.held = list(correction)
        if self.kind == "kuka_rsi":
            k = self.s.kuka_rsi
            if k.cartesian:
                m = self.tcp_motion(q, correction)
                values = [*m[:3], m[5], m[4], m[3]]        # RKorr A, B, C turn about Z, Y, X
            else:
                values = correction
            if k.correction == "relative":
                values, self.sent = [v - s for v, s in zip(values, self.sent)], list(values)
            return self.codec.answer(k.sen_type, p.stamp, values, k.cartesian)
        self.seqno += 1
        if self.s.abb_egm.mode == "joint":
            return self.codec.joint_answer(self.seqno, [a + b for a, b in zip(p.joints_deg, correction)])
        d = self.tcp_motion(q, correction)[:3]
        frame = self.codec.path_frame(self.last_pose, p.pose) if p.pose is not None else np.eye(3)
        self.last_pose = p.pose
        return self.codec.path_answer(self.seqno, tuple(float(v) for v in np.asarray(frame).T @ d),
                                      round(max(age_ms, 0.0)))
