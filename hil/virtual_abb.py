"""A virtual ABB controller over EGM, as ABB's Application manual Externally Guided Motion (RobotWare 7,
3HAC073318-001) defines it.

* **Position guidance** (joint mode, ``EGMRunJoint``): the robot follows no RAPID path. ``planned`` in its
  ``EgmRobot`` is its *reference position*, which moves toward the last target the sensor sent through EGM's
  own filter: a speed of ``-ext_motion_Kp`` x (target - reference) (1/s), low-passed at
  ``-ext_motion_filter_bandwidth`` (Hz), the values of the shipped StiffCompMoc.cfg profile by default.
  ``feedBack`` lags the reference by the servo's lag.
* **Path correction** (path mode, ``EGMActMove`` and ``EGMMoveL``/``EGMMoveC``): the robot moves along its
  programmed path, and ``planned`` is that path. It reads the newest path correction at each sample
  (``\\SampleRate``, a multiple of 24 ms; its packets come at that rate) and lays the correction's y and z in the
  path frame over the path (not x, along the motion; not the orientation) until the next sample.

The controller interpolates every 4 ms either way; the header's ``seqno`` counts its packets from 1 again
when its program starts EGM again (`AbbController.restart`), and ``tm`` is its clock in ms.
"""

from __future__ import annotations

import math

import numpy as np

from robot_road import egm
from robot_road.packets import PacketError

from .virtual_robot import CLOCK0_MS, Delayed, RobotController, joints_for

IPO_S = 0.004               # the controller's interpolation cycle
SERVO_LAG_S = 0.008         # feedBack behind the reference
KP = 5.0                    # StiffCompMoc.cfg's StiffCompJoint -ext_motion_Kp (1/s)
BANDWIDTH_HZ = 20.0         # ... its -ext_motion_filter_bandwidth


class AbbController(RobotController):
    """An ABB controller's EGM side (module docstring).

    Parameters
    ----------
    kp, bandwidth_hz : position guidance's gain (1/s) and filter bandwidth (Hz)
    """

    period = IPO_S

    def __init__(self, settings, robot, delay_s: float = 0.0, kp: float = KP, bandwidth_hz: float = BANDWIDTH_HZ):
        super().__init__(settings, robot, delay_s)
        self.mode = settings.section.mode
        self.every = max(1, round(settings.section.cycle_ms / 1000.0 / IPO_S))
        self.kp = float(kp)
        self._smooth = 1.0 - math.exp(-2.0 * math.pi * bandwidth_hz * IPO_S)
        self._lag = 1.0 - math.exp(-IPO_S / SERVO_LAG_S)
        self.tm = 0
        self.restart()

    def restart(self) -> None:
        self.stamp = 0
        self.ref: np.ndarray | None = None                 # joint mode: the reference position (planned)
        self.speed = np.zeros(6)
        self.target = Delayed(None, self.delay_s)          # joint mode: the sensor's last target
        self.offset = Delayed(np.zeros(3), self.delay_s)   # path mode: the correction laid over the path, base, mm
        self.actual: np.ndarray | None = None              # feedBack
        self.frames = egm.PathFrames()                     # path mode: the path frame of each packet
        self._frame = None

    def packet(self, t: float, q_ref) -> bytes:
        self.stamp += 1
        self.tm = CLOCK0_MS + round(1000.0 * t)
        if self.mode == "joint":
            if self.ref is None:
                self.ref = np.array(q_ref, dtype=float)
            planned = self.ref
        else:
            planned = np.asarray(q_ref, dtype=float)
        if self.actual is None:
            self.actual = planned.copy()
        pose = self.pose(planned)
        if self.mode == "path":
            self._frame = self.frames.next(pose)
        return egm.robot_packet(self.stamp, self.tm, list(planned), list(self.actual), pose)

    def pose(self, q) -> tuple[float, ...]:
        """The TCP pose at joints ``q``: x, y, z (mm) and the quaternion qw, qx, qy, qz."""
        import pinocchio as pin

        T = self.robot.frames(np.radians(np.asarray(q))[None])[0, 7]
        c = pin.Quaternion(T[:3, :3]).coeffs()            # x, y, z, w
        return (*(1000.0 * T[:3, 3]), c[3], c[0], c[1], c[2])

    def take(self, data: bytes, t: float, q_ref) -> bool:
        try:
            _, kind, values, _, tm = egm.read_answer(data)
        except PacketError:
            return False
        if tm != self.tm:                          # an answer to an earlier packet, late
            return False
        self.answer = tuple(values)
        if kind == "joints":
            self.target.set(t, np.array(values))
        else:
            # the path frame from the planned poses of this packet and the one before, as the road reads them
            self.frame = self._frame
            self.offset.set(t, np.array(egm.to_base(self.frame, (0.0, values[1], values[2]))))   # across the path
        return True

    def commanded(self, t: float, q_ref) -> np.ndarray:
        if self.mode == "joint":
            if self.ref is None:
                self.ref = np.array(q_ref, dtype=float)
            target = self.target.at(t)
            if target is not None:
                self.speed += (self.kp * (target - self.ref) - self.speed) * self._smooth
                self.ref = self.ref + self.speed * IPO_S
            q = self.ref.copy()
        else:
            q = np.asarray(q_ref, dtype=float) + joints_for(self.jacobian, q_ref, self.offset.at(t), slice(0, 3))
        if self.actual is not None:
            self.actual += (q - self.actual) * self._lag
        return q

    def holds(self, t: float, q_ref) -> np.ndarray:
        if self.mode == "joint":
            target = self.target.at(t)
            return np.zeros(6) if target is None else target - np.asarray(q_ref, dtype=float)
        return joints_for(self.jacobian, q_ref, self.offset.at(t), slice(0, 3))
