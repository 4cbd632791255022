"""Virtual robot controllers that speak the real robot interfaces: KUKA RSI and ABB EGM over UDP.

The robot is the clock. Every ``cycle_ms`` (4 ms) the controller sends its packet to the sensor (the
service's robot road) and takes the answer that arrives before its next cycle:

* **KUKA RSI**: ``<Rob>`` with the axes' setpoints (``ASPos``: the programmed joints plus the correction the
  robot holds), ``Delay`` (late answers so far) and ``IPOC`` (ms); the answer must repeat the IPOC. ``AK`` is
  the joint correction, ``RKorr`` the TCP's (base frame), absolute (the whole offset) or relative (added up).
* **ABB EGM**: ``EgmRobot`` with its seqno, its clock, the planned joints and pose (the programmed path) and
  the feedback; joint mode takes the answer's joints as the position to hold; path mode takes the
  correction across the path (the path frame's y and z; its x, along the motion, is not corrected).

A missing or late answer leaves the correction as it was (relative RSI: adds nothing) and is counted; after
``timeout_count`` of them in a row the robot stops (RSI's ETHERNET timeout, EGM's comm timeout): it sends no
more packets and holds its last position, and `stopped_at` says when.
"""

from __future__ import annotations

import socket
import struct
import time

import numpy as np

from plc_interface.robot import rsi
from plc_interface.robot.answers import TcpJacobian
from plc_interface.robot.packets import PacketError
from plc_interface.robot.settings import RobotSettings
from stiffness.kinematics.spatial import damped_pinv_solve

SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)    # Linux's number where Python does not name it
IPOC0 = 1_000_000          # the controller's clock (ms) at program time 0: a stamp never below zero


def joints_for(jacobian: TcpJacobian, q_deg, target, rows: slice = slice(0, 6)) -> np.ndarray:
    """The joint correction (deg) whose TCP motion at ``q_deg`` (rows ``rows`` of J(q) dq) is ``target``: the
    controller's own inverse of the road's Cartesian answer (damped least squares)."""
    return damped_pinv_solve(jacobian(q_deg)[rows], 1e-6, np.asarray(target, dtype=float))


class RobotController:
    """The controller's side of one interface: its packets, and what an answer does to the correction.

    Parameters
    ----------
    settings : RobotSettings
        The same section the service reads (interface, cycle, absolute/relative, joint/Cartesian/path).
    robot : Robot, for the Cartesian and path answers (the controller's own kinematics)
    """

    def __init__(self, settings: RobotSettings, robot):
        self.s, self.robot = settings, robot
        self.jacobian = TcpJacobian(robot) if settings.cartesian else None
        self.kind = settings.interface
        if self.kind == "abb_egm":
            from plc_interface.robot import egm

            self.egm = egm
        self.period = settings.cycle_ms / 1000.0
        self.applied = np.zeros(6)              # the joint correction the robot holds (deg)
        self._cart = np.zeros(6)                # relative RKorr: the TCP correction added up
        self.stamp = 0
        self.tm = 0
        self.late = 0
        self.answer: tuple[float, ...] = ()     # the values of the last answer taken (AK, RKorr, joints, path)
        self._pose_prev = self._pose = self._x_prev = self.frame = None     # EGM path: the path frame (rows: x, y, z)

    def packet(self, t: float, q_ref) -> bytes:
        """The packet of the cycle at program time ``t`` (s) with programmed joints ``q_ref`` (deg)."""
        setpoint = np.add(q_ref, self.applied)
        if self.kind == "kuka_rsi":
            self.stamp = IPOC0 + round(1000.0 * t)
            return rsi.robot_packet(self.stamp, setpoint, setpoint, self.late)
        self.stamp += 1
        self.tm = IPOC0 + round(1000.0 * t)
        self._pose_prev, self._pose = self._pose, self.pose(q_ref)
        return self.egm.robot_packet(self.stamp, self.tm, list(q_ref), list(setpoint), self._pose)

    def pose(self, q_ref) -> tuple[float, ...]:
        """The planned TCP pose: x, y, z (mm) and the quaternion qw, qx, qy, qz."""
        import pinocchio as pin

        T = self.robot.frames(np.radians(np.asarray(q_ref))[None])[0, 7]
        c = pin.Quaternion(T[:3, :3]).coeffs()            # x, y, z, w
        return (*(1000.0 * T[:3, 3]), c[3], c[0], c[1], c[2])

    def take(self, data: bytes, q_ref) -> bool:
        """Apply one answer to the packet just sent; False when it is not that packet's answer."""
        try:
            if self.kind == "kuka_rsi":
                ipoc, tag, values = rsi.read_answer(data)
                if ipoc != self.stamp:
                    return False
                self.answer = values
                return self._rsi(tag, np.array(values), q_ref)
            _, kind, values, _, tm = self.egm.read_answer(data)
        except PacketError:
            return False
        if tm != self.tm:                          # an answer to an earlier packet, late
            return False
        self.answer = tuple(values)
        if kind == "joints":
            self.applied = np.subtract(values, q_ref)
        else:
            # the path frame from the planned poses of this packet and the one before, as the road reads them
            frame = self.egm.path_frame(self._pose_prev or self._pose, self._pose, self._x_prev)
            self._x_prev, self.frame = frame[0], frame
            d = self.egm.to_base(frame, (0.0, values[1], values[2]))      # across the path only
            self.applied = joints_for(self.jacobian, q_ref, d, slice(0, 3))
        return True

    def _rsi(self, tag: str, values: np.ndarray, q_ref) -> bool:
        relative = self.s.kuka_rsi.correction == "relative"
        if tag == "AK":
            self.applied = self.applied + values if relative else values
            return True
        m = np.array([*values[:3], values[5], values[4], values[3]])      # X Y Z, then C B A: about x, y, z
        self._cart = self._cart + m if relative else m
        self.applied = joints_for(self.jacobian, q_ref, self._cart)
        return True


class VirtualRobot:
    """A robot controller on its own clock, sending to the service's robot road over UDP.

    Parameters
    ----------
    controller : RobotController
    host, port : the service's robot road
    reference : t -> six programmed joints (deg)
    timeout_count : late answers in a row after which the robot stops
    """

    def __init__(self, controller: RobotController, host: str, port: int, reference, timeout_count: int = 100):
        self.c = controller
        self.address = (host, port)
        self.reference = reference
        self.timeout_count = int(timeout_count)
        self.sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.sock.setsockopt(socket.SOL_SOCKET, SO_TIMESTAMPNS, 1)
        self.sock.bind(("127.0.0.1", 0))
        self.in_a_row = 0
        self.stopped_at: float | None = None

    def close(self) -> None:
        self.sock.close()

    def _drain(self) -> None:
        """Answers that came after their cycle ended: counted late already, and left unapplied (an EGM answer
        names no packet, so one taken in the next cycle would pass for that cycle's)."""
        self.sock.setblocking(False)
        try:
            while True:
                self.sock.recv(65536)
        except (BlockingIOError, OSError):
            pass
        finally:
            self.sock.setblocking(True)

    def cycle(self, t: float, answer_by: float, clock=time.monotonic) -> tuple[bool, float]:
        """Send the packet of program time ``t``, take its answer if it arrives by clock time ``answer_by``:
        (answered in its cycle, round trip in s; NaN when late). The round trip runs from the send to the
        answer's arrival as the kernel stamped it (SO_TIMESTAMPNS), so a robot process that the host runs late
        neither lengthens it nor takes a late answer for one in time."""
        q_ref = self.reference(t)
        self._drain()
        packet = self.c.packet(t, q_ref)
        wall_by = time.time_ns() + int(1e9 * (answer_by - clock()))
        t_send = time.time_ns()
        self.sock.sendto(packet, self.address)
        while (left := answer_by - clock()) > 0:
            self.sock.settimeout(left)
            try:
                data, anc, _, _ = self.sock.recvmsg(65536, 64)
            except TimeoutError:
                break
            except OSError:                         # ICMP unreachable: the service is not there (yet)
                break
            t_got = arrival_ns(anc)
            if t_got <= wall_by and self.c.take(data, q_ref):
                self.in_a_row = 0
                return True, (t_got - t_send) / 1e9
        self.c.late += 1
        self.in_a_row += 1
        if self.in_a_row >= self.timeout_count and self.stopped_at is None:
            self.stopped_at = t
        return False, float("nan")


def arrival_ns(ancillary) -> int:
    """The kernel's receive stamp (ns, CLOCK_REALTIME) among a datagram's ancillary data; now without one."""
    for level, kind, data in ancillary:
        if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS and len(data) >= 16:
            sec, nsec = struct.unpack("qq", data[:16])
            return sec * 1_000_000_000 + nsec
    return time.time_ns()
