"""KUKA RSI's meaning to the road: IPOC, the axes' setpoints and what they hold, and the AK or RKorr answer.

Sources. KUKA.RobotSensorInterface 3.x/4.x manuals (the ETHERNET object, ``IPOC``, ``Delay``, ``AK``,
``RKorr``, ``#ABSOLUTE``/``#RELATIVE``); and a public recording of a KR C4's RSI 3 packets under an axis
correction (``debug_data.txt`` of the GitHub repository erensezener/kuka-rsi3-communicator, 2,863 packets,
cited, not copied: it carries no licence), in which ``ASPos`` stands still while ``AIPos`` moves by the
correction. So by default the road reads ``ASPos`` as the programmed joints and ``AIPos`` as holding the
correction (`KukaRsiSettings.includes_correction`).

* **Stamp**: IPOC, the controller's clock in ms, rising by ``cycle_ms`` per packet; a new ``RSI_ON`` starts it
  again lower, which begins a new session at once (`RobotInterface.restarted`).
* **Joints**: the programmed joints are the element's A1..A6, less the correction the robot holds where the
  element holds it.
* **Answer**: ``AK`` (the joint correction, deg) or ``RKorr`` (J(q) dq in the base frame, mm, and ZYX angles),
  absolute or, for ``#RELATIVE``, the change since the last answer; the IPOC repeated.
* **Check**: where the packet carries both ``ASPos`` and ``AIPos``, ``AIPos`` is fitted, once the robot holds a
  correction that varies enough to tell, to the servo following ``ASPos`` plus s times the held correction: s
  near 1 says ``ASPos`` does not hold the correction, near 0 that it does. A fit that contradicts the setting is
  a warning naming the key and the slope (`JointsCheck`).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from stiffness.files.yaml_schema import Strict

from . import rsi
from .interface import RobotInterface
from .packets import RobotPacket
from .registry import Declaration, declare
from .tcp import rkorr

XML_NAME = r"^[A-Za-z_][A-Za-z0-9_.-]{0,63}$"

CHECK_PACKETS = 125             # packets per fit of the joints check (0.5 s at 4 ms)
CHECK_LEAST_DEG = 0.001         # the held correction's spread (rms about its mean, deg) a fit needs on some axis:
                                # ten times the 1e-4 deg of the packets at the ETHERNET object's Precision 4


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
        ``AIPos`` does. The road checks it against the packets (`robot_road.kuka_rsi`)
    command_element, heartbeat_element, payload_element : names of optional elements the robot's program
        sends with the command word, a heartbeat and the payload index (None: not sent)
    """

    sen_type: str = Field("ImFree", pattern=XML_NAME)
    correction: Literal["absolute", "relative"] = "absolute"
    cartesian: bool = False
    cycle_ms: Literal[4, 12] = 4
    joints: Literal["ASPos", "AIPos"] = "ASPos"
    joints_include_correction: bool | None = None
    command_element: str | None = Field(None, pattern=XML_NAME)
    heartbeat_element: str | None = Field(None, pattern=XML_NAME)
    payload_element: str | None = Field(None, pattern=XML_NAME)

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


class JointsCheck:
    """Whether ``ASPos`` holds the correction, from the packets: per window of `CHECK_PACKETS` packets with a held
    correction that varies enough to tell, the least-squares slope s of

        AIPos - L(ASPos) = s L(h) + c        (per axis; one s for all axes)

    with h the correction the robot holds and L the servo's lag, a first-order lag of time constant tau, taken
    from `LAGS_S` as the one that fits best. If ASPos does not hold the correction, the servo follows
    ASPos + h and s is 1; if it does, the servo follows ASPos (h already in it) and s is 0. The lag is modelled,
    not regressed away on the joints' speed, because a correction that changes slowly along a smooth motion is
    nearly proportional to the speed over a window and would be taken for lag. ``slope`` is the last window's s
    (NaN before one was fitted).

    Parameters
    ----------
    period_s : the robot's cycle (s)
    """

    LAGS_S = np.arange(0.0, 0.0405, 0.002)

    def __init__(self, period_s: float):
        self.alpha = 1.0 - np.exp(-period_s / np.maximum(self.LAGS_S, 1e-9))[:, None]    # (lags, 1)
        self.slope = float("nan")
        self.windows = 0
        self.reset()

    def reset(self) -> None:
        self._ls = self._lh = None              # the lagged setpoints and held correction, per lag (lags, 6)
        self._n = 0
        g = len(self.LAGS_S)
        self._sx, self._sy, self._sxx, self._sxy, self._syy = (np.zeros((g, 6)) for _ in range(5))

    def add(self, p: RobotPacket, held) -> float | None:
        """Take one packet; the slope when a window closed with enough to tell, else None."""
        if p.setpoint_deg is None or p.actual_deg is None:
            return None
        sp, h = np.asarray(p.setpoint_deg), np.asarray(held, dtype=float)
        if self._ls is None:
            self._ls, self._lh = np.tile(sp, (len(self.LAGS_S), 1)), np.tile(h, (len(self.LAGS_S), 1))
        self._ls += self.alpha * (sp - self._ls)
        self._lh += self.alpha * (h - self._lh)
        x, y = self._lh, np.asarray(p.actual_deg) - self._ls
        self._sx += x
        self._sy += y
        self._sxx += x * x
        self._sxy += x * y
        self._syy += y * y
        self._n += 1
        if self._n < CHECK_PACKETS:
            return None
        n = self._n
        sxx = (self._sxx - self._sx ** 2 / n).sum(axis=1)           # per lag, about each axis's mean
        sxy = (self._sxy - self._sx * self._sy / n).sum(axis=1)
        syy = (self._syy - self._sy ** 2 / n).sum(axis=1)
        self._n = 0
        for a in (self._sx, self._sy, self._sxx, self._sxy, self._syy):
            a[:] = 0.0
        if sxx.max() < n * CHECK_LEAST_DEG ** 2:
            return None
        slope = np.divide(sxy, sxx, out=np.zeros_like(sxy), where=sxx > 0)
        best = int(np.argmin(syy - slope * sxy))                     # the residual of each lag's fit
        self.slope = float(slope[best])
        self.windows += 1
        return self.slope


class KukaRsi(RobotInterface):
    """KUKA RSI over Ethernet (module docstring)."""

    stamp_name = "IPOC"
    stamp_unit = "ms"

    def __init__(self, settings, robot_file=None):
        self.section = settings.section
        self.stamp_step = self.section.cycle_ms                  # IPOC counts milliseconds
        self.check = JointsCheck(self.section.cycle_ms / 1000.0) if self.section.joints == "ASPos" else None
        self._said: bool | None = None                     # the last verdict warned about
        super().__init__(settings, robot_file)

    def restart(self) -> None:
        super().restart()
        if self.check is not None:                          # set before the base class restarts
            self.check.reset()

    def parse(self, data: bytes) -> RobotPacket:
        return rsi.parse(data, self.section)

    def programmed(self, p: RobotPacket, held, new_session: bool) -> list[float]:
        if self.section.includes_correction and not new_session:
            return [q - h for q, h in zip(p.joints_deg, held)]
        return list(p.joints_deg)

    def answer(self, p: RobotPacket, q: list[float], correction: list[float], age_ms: float) -> bytes:
        k = self.section
        values = rkorr(self.jacobian.motion(q, correction)) if k.cartesian else tuple(correction)
        sent = values
        if k.correction == "relative":
            sent = tuple(v - s for v, s in zip(values, self.history[-1][1]))
        self.hold(correction, values)
        return rsi.answer(k.sen_type, p.stamp, sent, k.cartesian)

    def evidence(self, p: RobotPacket) -> tuple[str, str] | None:
        if self.check is None:
            return None
        slope = self.check.add(p, self.held)
        if slope is None:
            return None
        holds = slope < 0.5
        if holds == self.section.includes_correction:
            self._said = None
            return None
        if self._said == holds:
            return None
        self._said = holds
        setting = str(self.section.includes_correction).lower()
        return "joints_include_correction", (
            f"robot.kuka_rsi.joints_include_correction is {setting}, but the robot's packets say ASPos "
            f"{'holds' if holds else 'does not hold'} the correction: AIPos - ASPos follows the held correction with "
            f"a slope of {slope:.2f} over {CHECK_PACKETS} packets (1: ASPos without it, 0: with it); set "
            f"joints_include_correction: {str(holds).lower()} (docs/robot.md, \"Which joints the cycle uses\")")

    def check_stats(self) -> dict:
        if self.check is None:
            return {}
        s = self.check.slope
        fitted = not math.isnan(s)
        return {"joints_check": {"slope": round(s, 3) if fitted else None, "windows": self.check.windows,
                                 "agrees": (s < 0.5) == self.section.includes_correction if fitted else None}}


DECLARATION = declare(Declaration("kuka_rsi", "KUKA RSI", KukaRsiSettings, KukaRsi, "hil.virtual_kuka:KukaController"))
