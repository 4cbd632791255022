"""What both robot interfaces' packets come down to, and the error a bad one raises."""

from __future__ import annotations

from typing import NamedTuple


class PacketError(ValueError):
    """A packet that is not the robot's, or not whole: it is counted under ``reason`` and dropped."""

    def __init__(self, reason: str, detail: str):
        super().__init__(detail)
        self.reason = reason            # the metrics' label: malformed, ipoc, joints, ...


class RobotPacket(NamedTuple):
    """One packet from the robot, read.

    stamp : the robot's own count (RSI's IPOC, EGM's header seqno): the answer repeats IPOC, and a stamp
        that does not rise is refused
    joints_deg : the axes' programmed positions as the packet gives them (deg)
    late : the robot's own count of late answers so far (RSI's ``Delay``; None where the packet has none)
    command, heartbeat, payload : the optional values the robot's program sends (None: absent)
    tm_ms : the robot's clock (EGM's header tm, ms), or None
    pose : the planned TCP pose (x, y, z in mm, then the quaternion qw, qx, qy, qz), or None
    setpoint_deg, actual_deg : the axes' setpoints and measured positions where the packet carries both (RSI's
        ``ASPos`` and ``AIPos``; EGM's ``planned`` and ``feedBack``), for the checks of what the joints hold
    """

    stamp: int
    joints_deg: tuple[float, ...]
    late: int | None = None
    command: int | None = None
    heartbeat: int | None = None
    payload: int | None = None
    tm_ms: int | None = None
    pose: tuple[float, ...] | None = None
    setpoint_deg: tuple[float, ...] | None = None
    actual_deg: tuple[float, ...] | None = None
