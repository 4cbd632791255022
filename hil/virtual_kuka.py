"""A virtual KUKA KR C4 over RSI (Ethernet), as the real one behaves.

What its packet holds is taken from a public recording of a KR C4's RSI 3 packets under an axis correction
(``debug_data.txt`` of the GitHub repository erensezener/kuka-rsi3-communicator, 2,863 packets; cited, not
copied): ``ASPos`` stands still while ``AIPos`` moves by the correction. So here

* ``ASPos`` is the programmed joints (``aspos_holds_correction=True`` makes the other kind, for tests);
* ``AIPos`` is the commanded joints, programmed plus the correction the robot holds, behind by the servo's lag
  (a first-order lag of `SERVO_LAG_S`);
* ``IPOC`` is the controller's clock in ms; ``Delay`` counts the answers that came late; a new ``RSI_ON``
  (`KukaController.restart`) starts the IPOC again lower and drops the correction.

An answer ``AK`` is the joint correction (absolute: the whole offset; relative: an increment added up);
``RKorr`` the TCP's motion in the base frame, turned back into joints by the controller's own inverse.
"""

from __future__ import annotations

import math

import numpy as np

from robot_road import rsi
from robot_road.packets import PacketError
from robot_road.tcp import motion_of_rkorr

from .virtual_robot import CLOCK0_MS, Delayed, RobotController, joints_for

SERVO_LAG_S = 0.008         # AIPos behind the commanded joints: the position loop's lag (a few IPO cycles)
RESTART_BACK_MS = 60_000    # how far a new RSI_ON starts the IPOC below the last one


class KukaController(RobotController):
    """A KR C4's RSI side (module docstring).

    Parameters
    ----------
    aspos_holds_correction : ASPos holds the correction the robot applies (not what a KR C4 does)
    extra : element name -> value of the elements the robot program sends (the command word ...)
    """

    def __init__(self, settings, robot, delay_s: float = 0.0, aspos_holds_correction: bool = False,
                 extra: dict[str, int] | None = None):
        super().__init__(settings, robot, delay_s)
        self.section = settings.section
        self.period = self.section.cycle_ms / 1000.0
        self.aspos_holds = aspos_holds_correction
        self.extra = dict(extra or {})
        self.clock0 = CLOCK0_MS
        self.restart()

    def restart(self) -> None:
        self.clock0 -= RESTART_BACK_MS if self.stamp else 0
        self.held = Delayed(np.zeros(6), self.delay_s)     # the joint correction the robot holds
        self._target = np.zeros(6)                          # ... as the last answer set it
        self._cart = np.zeros(6)                            # relative RKorr: the TCP correction added up
        self.actual: np.ndarray | None = None               # AIPos
        self._late0 = self.late                             # Delay counts from RSI_ON

    def packet(self, t: float, q_ref) -> bytes:
        applied = self.held.at(t)
        commanded = np.add(q_ref, applied)
        if self.actual is None:
            self.actual = commanded.copy()
        self.stamp = self.clock0 + round(1000.0 * t)
        aspos = commanded if self.aspos_holds else np.asarray(q_ref, dtype=float)
        return rsi.robot_packet(self.stamp, aspos, self.actual, self.late - self._late0, self.extra)

    def take(self, data: bytes, t: float, q_ref) -> bool:
        try:
            ipoc, tag, values = rsi.read_answer(data)
        except PacketError:
            return False
        if ipoc != self.stamp:
            return False
        self.answer = values
        v = np.array(values)
        relative = self.section.correction == "relative"
        if tag == "AK":
            self._target = self._target + v if relative else v
        else:
            m = np.array(motion_of_rkorr(v))
            self._cart = self._cart + m if relative else m
            self._target = joints_for(self.jacobian, q_ref, self._cart)
        self.held.set(t, self._target)
        return True

    def commanded(self, t: float, q_ref) -> np.ndarray:
        q = np.add(q_ref, self.held.at(t))
        if self.actual is not None:
            self.actual += (q - self.actual) * (1.0 - math.exp(-self.period / SERVO_LAG_S))
        return q

    def holds(self, t: float, q_ref) -> np.ndarray:
        return np.array(self.held.at(t))
