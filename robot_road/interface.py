"""What every robot interface is to the road, and the registry that finds one by its name.

`RobotRoad` (road.py) holds what all interfaces share: the peer, the sessions, the stamps' order, the limits,
the command word and heartbeat, the ramp and the counts. An interface (`kuka_rsi.KukaRsi`, `abb_egm.AbbEgm`)
holds what its maker defines, in one module each, through these hooks (as python-can's interfaces override
``BusABC._recv_internal``):

* `parse`: one datagram read into a `RobotPacket`, or PacketError;
* `restarted`: whether a stamp that does not rise begins a new session (the robot's program started the
  interface again: RSI's IPOC falls back after a new ``RSI_ON``, EGM's seqno after a new ``EGMRunJoint``)
  rather than being a duplicate or a reordered packet;
* `programmed`: the programmed joints, from what the packet's joints hold and what the robot holds;
* `answer`: the answer for a joint correction.

What the robot holds of the correction is kept here for every interface: the joint correction behind each
answer, newest last, so that an answer the robot reports missing (RSI's ``Delay``) is taken back.

Another interface (e.g. Staubli's or Fanuc's) is one module holding its settings, its `RobotInterface` and its
declaration (`registry.declare`), and the HIL's virtual controller the declaration names.
"""

from __future__ import annotations

from collections import deque

from .packets import RobotPacket
from .settings import RobotSettings

ZERO6 = (0.0,) * 6
HISTORY = 64                    # answers remembered for a robot that reports it missed some (RSI's Delay)
RESTART_STEPS = 25              # a stamp this many steps (cycles) below the last begins a new session



def interface_for(settings: RobotSettings, robot_file: str | None = None) -> RobotInterface:
    """The road's side of the interface ``settings.interface`` names, as its declaration gives it."""
    return settings.declaration.road(settings, robot_file)


class RobotInterface:
    """One robot interface's meaning: its packets, its sessions, its joints and its answers.

    Parameters
    ----------
    settings : RobotSettings
    robot_file : the model's robot (YAML), for the answers that carry the TCP's motion
    """

    stamp_step = 1              # how much the stamp rises per robot cycle
    stamp_name = "stamp"        # the maker's name for the stamp, as the road's warnings say it
    stamp_unit = "steps"        # what the stamp counts, as the road's warnings say it

    def __init__(self, settings: RobotSettings, robot_file: str | None = None):
        self.settings = settings
        self.jacobian = None
        if settings.cartesian:
            from stiffness.kinematics.robot import load_robot

            from .tcp import TcpJacobian

            if robot_file is None:
                raise ValueError("a Cartesian answer needs the robot's kinematics (the model's robot file)")
            self.jacobian = TcpJacobian(load_robot(robot_file))
        self.restart()

    # -- what the robot holds ---------------------------------------------------------------------------
    def restart(self) -> None:
        """A new session: the robot holds no correction."""
        # after each answer, newest last: (the joint correction behind it, the values the robot adds up to)
        self.history: deque[tuple[tuple[float, ...], tuple[float, ...]]] = deque([(ZERO6, ZERO6)], maxlen=HISTORY)

    def missed(self, n: int) -> None:
        """The robot says it did not take the last ``n`` answers: it holds what it held before them."""
        for _ in range(min(n, len(self.history) - 1)):
            self.history.pop()

    @property
    def held(self) -> tuple[float, ...]:
        """The joint correction (deg) the robot holds: the one behind the last answer it took."""
        return self.history[-1][0]

    def held_before(self, missed: int) -> tuple[float, ...]:
        """What the robot holds if it did not take the last ``missed`` answers (RSI's ``Delay`` rose by that)."""
        return self.history[-1 - min(missed, len(self.history) - 1)][0]

    def hold(self, correction, values) -> None:
        """Remember an answer: the joint ``correction`` behind it and the ``values`` the robot holds once it takes
        it (for a relative answer, the total of the increments)."""
        self.history.append((tuple(correction), tuple(values)))

    # -- the hooks ----------------------------------------------------------------------------------------
    def parse(self, data: bytes) -> RobotPacket:
        raise NotImplementedError

    def restarted(self, stamp: int, last: int) -> bool:
        """Whether ``stamp``, not above the ``last`` one taken, begins a new session: it fell back by more than
        `RESTART_STEPS` cycles (a duplicate or a packet a few cycles out of order does not)."""
        return stamp < last - RESTART_STEPS * self.stamp_step

    def programmed(self, p: RobotPacket, held, new_session: bool) -> list[float]:
        """The programmed joints (deg) of packet ``p``, while the robot holds the joint correction ``held``."""
        raise NotImplementedError

    def answer(self, p: RobotPacket, q: list[float], correction: list[float], age_ms: float) -> bytes:
        """The answer to ``p`` whose programmed joints are ``q``, for the joint ``correction`` (deg), remembered
        as what the robot holds once it takes it."""
        raise NotImplementedError

    def evidence(self, p: RobotPacket) -> tuple[str, str] | None:
        """(the setting's key, a warning) when the packets contradict a setting about what they hold (None:
        nothing to say, or said already)."""
        return None

    def check_stats(self) -> dict:
        """The figures of the interface's own checks, for the road's stats."""
        return {}
