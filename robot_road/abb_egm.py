"""ABB EGM's meaning to the road: the seqno, what ``planned`` is, and the joint or path-correction answer.

Source: ABB's Application manual Externally Guided Motion (RobotWare 7, 3HAC073318-001). Two of its facts decide
the answers:

* ``planned`` in ``EgmRobot`` is the robot's *reference position*, the target it is moving to, not a programmed
  path; and in position guidance (``EGMRunJoint``) the robot follows no RAPID path at all. So a joint answer of
  "``planned`` + δq" is added again every cycle by a robot that does what the manual says: the target runs
  away. Joint mode therefore answers the pose the robot reported when the session began (its ``planned``
  joints in the session's first packet) plus δq: the pose it holds, whatever the controller fills ``planned``
  with afterwards. It is for a pose held under load (drilling, a plunge, a press fit), not a cut.
* A programmed path is corrected by path correction (``EGMActMove``, ``EGMMoveL``/``EGMMoveC``), read by the
  controller at multiples of about 24 ms. The answer is J(q) δq, the TCP's motion, in ABB's path frame
  (`egm.path_frame`), with the age of the force sample it comes from (at least 1 ms: the manual's age counts
  whole milliseconds since the measurement, and a public sender never sends less than 1). Its value is absolute
  (the offset from the programmed path), so it cannot add up either way ``planned`` is filled.

* **Stamp**: the header's seqno, rising by one per packet; a new ``EGMRunJoint`` or ``EGMActMove`` starts it
  again, which begins a new session at once.
* **Joints**: joint mode, the session's first planned joints; path mode, the planned joints (the robot's
  position on its programmed path).
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from stiffness.files.yaml_schema import Strict

from . import egm
from .interface import RobotInterface
from .packets import PacketError, RobotPacket
from .registry import Declaration, declare

MIN_AGE_MS = 1
PATH_SAMPLE_MS = 24        # EGM path corrections are read at multiples of this (ABB's EGM manual)


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



class AbbEgm(RobotInterface):
    """ABB EGM over UDP (module docstring)."""

    stamp_name = "seqno"
    stamp_unit = "packets"

    def __init__(self, settings, robot_file=None):
        self.mode = settings.section.mode
        self.seqno = 0                  # the sensor's own rising count
        self.hold_pose: list[float] | None = None       # joint mode: the pose of the session's first packet
        super().__init__(settings, robot_file)

    def restart(self) -> None:
        """A new session (after `programmed` read its first packet, which sets the pose joint mode holds)."""
        super().restart()
        self.frames = egm.PathFrames()                      # path mode: the path frame, packet by packet

    def restarted(self, stamp: int, last: int) -> bool:
        # a new EGM instruction counts from the start again (however short the last one was)
        return super().restarted(stamp, last) or stamp <= 1 < last

    def parse(self, data: bytes) -> RobotPacket:
        p = egm.parse(data)
        if self.mode == "path" and p.pose is None:
            raise PacketError("pose", "no planned.cartesian pose (pos and orient): a path correction is given in "
                                      "the path frame, which the planned poses define")
        return p

    def programmed(self, p: RobotPacket, held, new_session: bool) -> list[float]:
        if self.mode == "path":
            return list(p.joints_deg)
        if new_session or self.hold_pose is None:          # the pose the robot reported as the session began
            self.hold_pose = list(p.joints_deg)
        return list(self.hold_pose)

    def answer(self, p: RobotPacket, q: list[float], correction: list[float], age_ms: float) -> bytes:
        self.seqno += 1
        self.hold(correction, correction)
        if self.mode == "joint":
            return egm.joint_answer(self.seqno, [a + b for a, b in zip(q, correction)], p.tm_ms)
        d = self.jacobian.motion(q, correction)[:3]
        frame = self.frames.next(p.pose)
        return egm.path_answer(self.seqno, egm.to_path(frame, d), max(round(age_ms), MIN_AGE_MS), p.tm_ms)


DECLARATION = declare(Declaration("abb_egm", "ABB EGM", AbbEgmSettings, AbbEgm, "hil.virtual_abb:AbbController"))
