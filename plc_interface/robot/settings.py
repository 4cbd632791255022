"""The ``robot:`` section of the service config: which real-time robot interface the I/O process answers.

Attributes of `RobotSettings`
-----------------------------
interface : ``none`` (the PLC alone, the default), ``kuka_rsi`` or ``abb_egm``
host, port : where the service listens for the robot's UDP packets (the robot sends to this address)
peer : the robot controller's IP address; packets from any other address are dropped, counted and logged
    once. None takes any sender (a warning at start when ``host`` is not a loopback address)
realtime_priority : SCHED_FIFO priority of the I/O process, which answers the robot (0: normal scheduling);
    below the cycle's ``cycle.realtime_priority``, so the 1 ms cycle still comes first
kuka_rsi, abb_egm : each interface's own settings
"""

from __future__ import annotations

import ipaddress
from typing import Literal

from pydantic import Field, field_validator

from stiffness.files.yaml_schema import Strict

from ..settings import PORT_MAX, PORT_MIN, is_loopback, peer_address

INTERFACES = ("none", "kuka_rsi", "abb_egm")
_XML_NAME = r"^[A-Za-z_][A-Za-z0-9_.-]{0,63}$"


class KukaRsiSettings(Strict):
    """``robot.kuka_rsi``: what the robot's RSI configuration (its ETHERNET object) says.

    Attributes
    ----------
    sen_type : the ``Type`` of the answer's ``<Sen>`` element, as the RSI configuration names it
    correction : ``absolute`` (AK/RKorr is the whole offset from the programmed path) or ``relative``
        (an increment per cycle), as the robot's AXISCORR/POSCORR object is set
    cartesian : false: ``AK A1..A6``, the joint correction in degrees; true: ``RKorr X Y Z A B C``, the TCP
        motion the joint correction makes, in the base frame (mm, deg)
    cycle_ms : the robot's RSI cycle, 4 (KR C4 and later) or 12
    joints : the element whose A1..A6 are the axes' setpoints the cycle uses (``ASPos``; ``AIPos``: actual)
    joints_include_correction : the robot's setpoints already hold the correction this service sent, which is
        taken off again so the cycle sees the programmed joints
    command_element, heartbeat_element, payload_element : names of optional elements the robot's program
        sends with the command word, a heartbeat and the payload index (None: not sent)
    """

    sen_type: str = Field("ImFree", pattern=_XML_NAME)
    correction: Literal["absolute", "relative"] = "absolute"
    cartesian: bool = False
    cycle_ms: Literal[4, 12] = 4
    joints: Literal["ASPos", "AIPos"] = "ASPos"
    joints_include_correction: bool = True
    command_element: str | None = Field(None, pattern=_XML_NAME)
    heartbeat_element: str | None = Field(None, pattern=_XML_NAME)
    payload_element: str | None = Field(None, pattern=_XML_NAME)


class AbbEgmSettings(Strict):
    """``robot.abb_egm``: how the answer guides the robot.

    Attributes
    ----------
    mode : ``joint``: position guidance; the answer's planned joints are the robot's planned joints plus the
        correction (EGMActJoint, EGMRunJoint). ``path``: a path correction (EGMActMove, EGMMoveL/EGMMoveC with
        path correction): the TCP motion the joint correction makes, in the path frame, with its age
    cycle_ms : the robot's EGM cycle (its UDP unit's sample rate), 4 by default
    """

    mode: Literal["joint", "path"] = "joint"
    cycle_ms: int = Field(4, ge=4, le=100)


class RobotSettings(Strict):
    interface: Literal[INTERFACES] = "none"
    host: str = "127.0.0.1"
    port: int = Field(49152, ge=PORT_MIN, le=PORT_MAX)
    peer: str | None = None
    realtime_priority: int = Field(0, ge=0, le=98)
    kuka_rsi: KukaRsiSettings = Field(default_factory=KukaRsiSettings)
    abb_egm: AbbEgmSettings = Field(default_factory=AbbEgmSettings)

    @field_validator("peer")
    @classmethod
    def _address(cls, v: str | None) -> str | None:
        return None if v is None else str(ipaddress.ip_address(v))

    @property
    def enabled(self) -> bool:
        return self.interface != "none"

    @property
    def cycle_ms(self) -> int:
        """The robot's cycle (ms) of the interface in use."""
        return self.kuka_rsi.cycle_ms if self.interface == "kuka_rsi" else self.abb_egm.cycle_ms

    @property
    def cartesian(self) -> bool:
        """Whether the answer carries the TCP's motion (RKorr, EGM path correction) rather than joints."""
        return (self.kuka_rsi.cartesian if self.interface == "kuka_rsi" else self.abb_egm.mode == "path")

    def takes(self, peer_ip: str) -> bool:
        """Whether a packet from ``peer_ip`` is the robot's (``peer``)."""
        return self.peer is None or peer_address(peer_ip) == ipaddress.ip_address(self.peer)

    def served(self) -> str:
        """The start-up line's words: ``KUKA RSI on 127.0.0.1:49152 (4 ms, AK absolute)``."""
        if self.interface == "kuka_rsi":
            k = self.kuka_rsi
            what = f"{'RKorr' if k.cartesian else 'AK'} {k.correction}"
            return f"KUKA RSI on {self.host}:{self.port} ({k.cycle_ms} ms, {what})"
        if self.interface == "abb_egm":
            return f"ABB EGM on {self.host}:{self.port} ({self.abb_egm.cycle_ms} ms, {self.abb_egm.mode} mode)"
        return "none"

    def exposure_warning(self) -> str | None:
        """The warning for a road that listens beyond this machine and takes any sender, or None."""
        if not self.enabled or self.peer is not None or is_loopback(self.host):
            return None
        return (f"the robot road listens on {self.host}:{self.port} and robot.peer is not set: every host that "
                "reaches this UDP port can send joints and receive the correction; set robot.peer to the robot "
                "controller's address (docs/robot.md)")
