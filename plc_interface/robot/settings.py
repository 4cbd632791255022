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

from pydantic import Field, field_validator, model_validator

from stiffness.files.yaml_schema import Strict

from ..settings import PORT_MAX, PORT_MIN, is_loopback, peer_address

INTERFACES = ("none", "kuka_rsi", "abb_egm")      # each but none has its sub-section and its module of the same name
NAMES = {"kuka_rsi": "KUKA RSI", "abb_egm": "ABB EGM"}
PATH_SAMPLE_MS = 24        # EGM path corrections are read at multiples of this (ABB's EGM manual)
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
    joints : the element whose A1..A6 are the joints the road reads (``ASPos``: the setpoints; ``AIPos``: the
        measured axes)
    joints_include_correction : whether those joints already hold the correction the robot applies. None (the
        default) takes what a real KR C4 does: ``ASPos`` does not hold it (a public recording of RSI 3 under
        correction shows ``ASPos`` standing still while ``AIPos`` moves by the correction, docs/robot.md),
        ``AIPos`` does. The road checks it against the packets (`plc_interface.robot.kuka_rsi`)
    command_element, heartbeat_element, payload_element : names of optional elements the robot's program
        sends with the command word, a heartbeat and the payload index (None: not sent)
    """

    sen_type: str = Field("ImFree", pattern=_XML_NAME)
    correction: Literal["absolute", "relative"] = "absolute"
    cartesian: bool = False
    cycle_ms: Literal[4, 12] = 4
    joints: Literal["ASPos", "AIPos"] = "ASPos"
    joints_include_correction: bool | None = None
    command_element: str | None = Field(None, pattern=_XML_NAME)
    heartbeat_element: str | None = Field(None, pattern=_XML_NAME)
    payload_element: str | None = Field(None, pattern=_XML_NAME)

    @property
    def includes_correction(self) -> bool:
        """Whether the joints the road reads hold the correction the robot applies (the setting, else the KR C4's
        behaviour: ``AIPos`` holds it, ``ASPos`` does not)."""
        return self.joints == "AIPos" if self.joints_include_correction is None else self.joints_include_correction

    @property
    def cartesian_answer(self) -> bool:
        return self.cartesian

    def served(self) -> str:
        return f"{self.cycle_ms} ms, {'RKorr' if self.cartesian else 'AK'} {self.correction}"

    def follows_no_path(self) -> str | None:
        """Why the robot, set so, runs no programmed path (None: RSI corrects the path the KRL program runs)."""
        return None


class AbbEgmSettings(Strict):
    """``robot.abb_egm``: how the answer guides the robot.

    Attributes
    ----------
    mode : ``path`` (the default, the shipped robot side): a path correction (EGMActMove, EGMMoveL/EGMMoveC with
        path correction): the TCP motion the joint correction makes, in the path frame, with its age.
        ``joint``: position guidance (EGMActJoint, EGMRunJoint), which runs no RAPID path: the answer is the pose
        the robot reported when the session began plus the correction, for a pose held under load
    cycle_ms : the robot's EGM cycle (the \\SampleRate of EGMActMove or EGMActJoint): in path mode a multiple of
        24 ms (ABB's manual: path corrections are read at multiples of about 24 ms; the shipped 48), in joint
        mode a multiple of 4 ms (4 by default)
    """

    mode: Literal["joint", "path"] = "path"
    cycle_ms: int | None = Field(None, ge=4, le=480)

    @model_validator(mode="after")
    def _sample_rate(self):
        step = PATH_SAMPLE_MS if self.mode == "path" else 4
        if self.cycle_ms is None:
            self.cycle_ms = 2 * PATH_SAMPLE_MS if self.mode == "path" else 4
        elif self.cycle_ms % step:
            raise ValueError(f"cycle_ms = {self.cycle_ms} must be a multiple of {step} ms in {self.mode} mode "
                             "(EGMAct" + ("Move" if self.mode == "path" else "Joint") + "'s \\SampleRate)")
        return self

    @property
    def cartesian_answer(self) -> bool:
        return self.mode == "path"

    def served(self) -> str:
        return f"{self.cycle_ms} ms, {self.mode} mode"

    @property
    def command_element(self) -> None:
        """EGM's messages carry no command word of the robot's own: the road's enable is ``plc.enable_on_start``."""
        return None

    def follows_no_path(self) -> str | None:
        """Why the robot, set so, runs no programmed path (None: path correction corrects the one it runs)."""
        if self.mode == "joint":
            return "robot.abb_egm.mode joint is position guidance, which runs no RAPID path (ABB's EGM manual)"
        return None


class RobotSettings(Strict):
    interface: Literal[INTERFACES] = "none"
    host: str = "127.0.0.1"
    port: int = Field(49152, ge=PORT_MIN, le=PORT_MAX)
    peer: str | None = None
    realtime_priority: int = Field(0, ge=0, le=98)
    kuka_rsi: KukaRsiSettings = Field(default_factory=KukaRsiSettings)
    abb_egm: AbbEgmSettings = Field(default_factory=AbbEgmSettings)

    def defaults_warning(self) -> str | None:
        """The warning for an interface named without its own sub-section (it runs on that section's defaults,
        which are the shipped robot side's), or None."""
        if not self.enabled or self.interface in self.model_fields_set:
            return None
        return (f"robot.interface is {self.interface} but the config has no robot.{self.interface} section: its "
                f"defaults are used ({self.section.served()}); they match the shipped robot side in robot/, so a "
                f"robot set up otherwise needs robot.{self.interface} (docs/config.md)")

    @field_validator("peer")
    @classmethod
    def _address(cls, v: str | None) -> str | None:
        return None if v is None else str(ipaddress.ip_address(v))

    @property
    def enabled(self) -> bool:
        return self.interface != "none"

    @property
    def section(self) -> KukaRsiSettings | AbbEgmSettings:
        """The sub-section of the interface in use (``robot.kuka_rsi``, ``robot.abb_egm``)."""
        return getattr(self, self.interface)

    @property
    def cycle_ms(self) -> int:
        """The robot's cycle (ms) of the interface in use."""
        return self.section.cycle_ms

    @property
    def cartesian(self) -> bool:
        """Whether the answer carries the TCP's motion (RKorr, EGM path correction) rather than joints."""
        return self.section.cartesian_answer

    @property
    def command_element(self) -> str | None:
        """The element of the robot's packets that carries its own command word (``robot.<interface>.
        command_element``), None when the robot sends none (EGM's messages have no such field)."""
        return self.section.command_element if self.enabled else None

    def takes(self, peer_ip: str) -> bool:
        """Whether a packet from ``peer_ip`` is the robot's (``peer``)."""
        return self.peer is None or peer_address(peer_ip) == ipaddress.ip_address(self.peer)

    def served(self) -> str:
        """The start-up line's words: ``KUKA RSI on 127.0.0.1:49152 (4 ms, AK absolute)``."""
        if not self.enabled:
            return "none"
        return f"{NAMES[self.interface]} on {self.host}:{self.port} ({self.section.served()})"

    def exposure_warning(self) -> str | None:
        """The warning for a road that listens beyond this machine and takes any sender, or None."""
        if not self.enabled or self.peer is not None or is_loopback(self.host):
            return None
        return (f"the robot road listens on {self.host}:{self.port} and robot.peer is not set: every host that "
                "reaches this UDP port can send joints and receive the correction; set robot.peer to the robot "
                "controller's address (docs/robot.md)")
