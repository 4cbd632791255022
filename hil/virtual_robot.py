"""Virtual robot controllers that speak the real robot interfaces over UDP, and the loop that drives one.

The robot is the clock. The controller interpolates on its own cycle (`RobotController.period`: RSI's 4 or 12
ms, EGM's 4 ms), sends its packet to the sensor (the service's robot road) every `RobotController.every`
cycles (EGM path corrections: every 48 ms) and takes the answer that arrives within the cycle. What each
interface's packets hold and what its answers do is the interface's own module, written from its maker's
manual or a real recording, as the road's is (`robot_road.interface`):

* `hil.virtual_kuka.KukaController`: KUKA RSI as a real KR C4 behaves;
* `hil.virtual_abb.AbbController`: ABB EGM as ABB's EGM manual defines it.

A missing or late answer leaves the correction as it was (relative RSI: adds nothing) and is counted; after
``timeout_count`` of them in a row the robot stops (RSI's ETHERNET ``Timeout``, EGM's ``\\CommTimeout``): it
sends no more packets and holds its last position, and `VirtualRobot.stopped_at` says when.
"""

from __future__ import annotations

import socket
import struct
import time
from collections import deque

import numpy as np

from io_base.deadlines import Deadlines
from robot_road import registry
from robot_road.settings import RobotSettings
from robot_road.tcp import TcpJacobian
from stiffness.kinematics.spatial import damped_pinv_solve

SO_TIMESTAMPNS = getattr(socket, "SO_TIMESTAMPNS", 35)    # Linux's number where Python does not name it
CLOCK0_MS = 1_000_000      # the controller's clock (ms) at program time 0: a stamp never below zero
TIMEOUT_COUNT = 100        # late answers in a row before the robot stops (the HIL's: a loaded host's stalls)



def controller_for(settings: RobotSettings, robot, **options) -> RobotController:
    """The virtual controller of ``settings.interface``, as the interface's declaration names it
    (`robot_road.registry`)."""
    return registry.load(settings.declaration.controller)(settings, robot, **options)


def joints_for(jacobian: TcpJacobian, q_deg, target, rows: slice = slice(0, 6)) -> np.ndarray:
    """The joint correction (deg) whose TCP motion at ``q_deg`` (rows ``rows`` of J(q) dq) is ``target``: the
    controller's own inverse of the road's Cartesian answer (damped least squares)."""
    return damped_pinv_solve(jacobian(q_deg)[rows], 1e-6, np.asarray(target, dtype=float))


class Delayed:
    """A value that takes effect ``delay_s`` after it was set (the HIL's ``--extra-delay-ms``)."""

    def __init__(self, value, delay_s: float = 0.0):
        self.delay = float(delay_s)
        self._q: deque = deque([(-np.inf, value)])

    def set(self, t: float, value) -> None:
        self._q.append((t, value))

    def at(self, t: float):
        """The newest value set at or before ``t - delay_s``."""
        while len(self._q) > 1 and self._q[1][0] <= t - self.delay + 1e-9:
            self._q.popleft()
        return self._q[0][1]


class RobotController:
    """The controller's side of one interface: its cycle, its packets, and what an answer does.

    Parameters
    ----------
    settings : RobotSettings
        The same section the service reads.
    robot : Robot, the controller's own kinematics (the Cartesian and path answers)
    delay_s : the answers take effect this much later (an extra delay of the robot's own)
    """

    period = 0.004              # the interpolation cycle (s): the log's rows, the servo's steps
    every = 1                   # a packet every this many cycles

    def __init__(self, settings: RobotSettings, robot, delay_s: float = 0.0):
        self.settings, self.robot = settings, robot
        self.jacobian = TcpJacobian(robot) if settings.cartesian else None
        self.delay_s = float(delay_s)
        self.stamp = 0
        self.late = 0
        self.answer: tuple[float, ...] = ()     # the values of the last answer taken
        self.frame = None                       # EGM path: the path frame of the last answer (rows: x, y, z)

    # -- the interface's hooks ----------------------------------------------------------------------
    def packet(self, t: float, q_ref) -> bytes:
        """The packet of the cycle at program time ``t`` (s) with programmed joints ``q_ref`` (deg)."""
        raise NotImplementedError

    def take(self, data: bytes, t: float, q_ref) -> bool:
        """Apply one answer to the packet just sent; False when it is not that packet's answer."""
        raise NotImplementedError

    def commanded(self, t: float, q_ref) -> np.ndarray:
        """The joints the servos are commanded to at ``t`` (deg), after this cycle's answer; the servo state
        (a filter, a lag) moves on by one cycle."""
        raise NotImplementedError

    def holds(self, t: float, q_ref) -> np.ndarray:
        """The joint correction (deg) the last answer taken asks for at ``t``, at programmed joints ``q_ref``."""
        raise NotImplementedError

    def restart(self) -> None:
        """The robot's program starts the interface again (RSI_ON, EGMRunJoint): its stamp starts again and it
        holds no correction."""
        raise NotImplementedError


class VirtualRobot:
    """A robot controller on its own clock, sending to the service's robot road over UDP.

    Parameters
    ----------
    controller : RobotController
    host, port : the service's robot road
    reference : t -> six programmed joints (deg)
    timeout_count : late answers in a row after which the robot stops
    """

    def __init__(self, controller: RobotController, host: str, port: int, reference,
                 timeout_count: int = TIMEOUT_COUNT):
        self.controller = controller
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
        """Answers that came after their cycle ended: counted late already, and left unapplied."""
        self.sock.setblocking(False)
        try:
            while True:
                self.sock.recv(65536)
        except (BlockingIOError, OSError):
            pass
        finally:
            self.sock.setblocking(True)

    def exchange(self, t: float, q_ref, answer_by: float, clock=time.monotonic,
                 stamp_t: float | None = None) -> tuple[bool, float]:
        """Send the packet of program time ``t`` (its stamp from the robot's clock at ``stamp_t``, by default
        ``t``), take its answer if it arrives by clock time ``answer_by``:
        (answered in its cycle, round trip in s; NaN when late). The round trip runs from the send to the
        answer's arrival as the kernel stamped it (SO_TIMESTAMPNS), so a robot process that the host runs late
        neither lengthens it, nor takes a late answer for one in time, nor misses one that came in time."""
        self._drain()
        packet = self.controller.packet(t if stamp_t is None else stamp_t, q_ref)
        wall_by = time.time_ns() + int(1e9 * (answer_by - clock()))
        t_send = time.time_ns()
        self.sock.sendto(packet, self.address)
        while True:
            # past the deadline, what is queued is still read once, without waiting: an answer the kernel
            # stamped in time counts although this process, on a shared host, came to read it late
            left = answer_by - clock()
            self.sock.settimeout(max(left, 0.0))
            try:
                data, anc, _, _ = self.sock.recvmsg(65536, 64)
            except (TimeoutError, BlockingIOError):
                break
            except OSError:                         # ICMP unreachable: the service is not there (yet)
                break
            t_got = arrival_ns(anc)
            if t_got <= wall_by and self.controller.take(data, t, q_ref):
                self.in_a_row = 0
                return True, (t_got - t_send) / 1e9
        self.controller.late += 1
        self.in_a_row += 1
        if self.in_a_row >= self.timeout_count and self.stopped_at is None:
            self.stopped_at = t
        return False, float("nan")


class Cycles:
    """Per interpolation cycle of a virtual robot's run, preallocated (`run_cycles` fills every row): the program
    time and its deadline, the programmed and commanded joints and the correction applied; per packet (``sent``)
    its stamp, whether its answer came in its cycle, the answer's values, the round trip (s), the path frame (EGM
    path) and how late the packet left after its deadline (the robot's own lateness); for the run the deadlines
    it exceeded (``overruns``)."""

    def __init__(self, n: int):
        self.t, self.due, self.sent_unix = np.full(n, np.nan), np.full(n, np.nan), np.full(n, np.nan)
        self.q_ref, self.q_cmd, self.applied = np.zeros((n, 6)), np.zeros((n, 6)), np.zeros((n, 6))
        self.sent, self.answered = np.zeros(n, dtype=bool), np.zeros(n, dtype=bool)
        self.stamp = np.zeros(n, dtype=np.int64)
        self.answer, self.frames = np.full((n, 6), np.nan), np.full((n, 3, 3), np.nan)
        self.rtt_s, self.send_lag_s = np.full(n, np.nan), np.zeros(n)
        self.overruns = 0


def run_cycles(vr: VirtualRobot, t_start: float, t_end: float, t0: float) -> Cycles:
    """The robot's cycles from program time ``t_start`` to ``t_end`` (program time = clock - ``t0``) on
    absolute deadlines: a packet every ``every`` cycles, its answer awaited until the next cycle is due. A
    robot that stopped (too many late answers) sends nothing more and holds where it stood."""
    c = vr.controller
    n = round((t_end - t_start) / c.period) + 1
    log = Cycles(n)
    deadlines = Deadlines(c.period, start=t0 + t_start)
    for k in range(n):
        deadlines.sleep_until()
        now = time.monotonic()
        # the cycle runs, and is logged, when it starts: a real controller's interpolation starts on its deadline,
        # this process on a shared host may start late (the catch-up rule then runs it at once on a deadline up to
        # a period past), and a cycle stamped with its deadline would carry a correction read later than its
        # time says, which shortens the measured end-to-end delay. The packet's stamp keeps the robot's own
        # clock, the deadline.
        t = now - t0
        log.t[k], log.due[k] = t, deadlines.due
        log.send_lag_s[k] = now - deadlines.due
        q_ref = np.asarray(vr.reference(t), dtype=float)
        log.q_ref[k] = q_ref
        if vr.stopped_at is None:
            if k % c.every == 0:
                log.sent[k], log.sent_unix[k] = True, time.time()
                log.answered[k], log.rtt_s[k] = vr.exchange(t, q_ref, deadlines.due + c.period,
                                                            stamp_t=deadlines.due - t0)
                log.stamp[k] = c.stamp
                if log.answered[k]:
                    log.answer[k, :len(c.answer)] = c.answer
                    if c.frame is not None:
                        log.frames[k] = c.frame
            log.q_cmd[k] = c.commanded(t, q_ref)
        else:
            log.q_cmd[k] = log.q_cmd[k - 1] if k else c.commanded(t, q_ref)
        log.applied[k] = log.q_cmd[k] - q_ref
        deadlines.advance(time.monotonic())
    log.overruns = deadlines.exceeded
    return log


def arrival_ns(ancillary) -> int:
    """The kernel's receive stamp (ns, CLOCK_REALTIME) among a datagram's ancillary data; now without one."""
    for level, kind, data in ancillary:
        if level == socket.SOL_SOCKET and kind == SO_TIMESTAMPNS and len(data) >= 16:
            sec, nsec = struct.unpack("qq", data[:16])
            return sec * 1_000_000_000 + nsec
    return time.time_ns()
