"""The payload table at run time: which set is in use, the PLC's selection, and the bumpless switch.

The PLC selects a set of ``gravity.payloads`` by writing its number to ``payload_index`` (0: the
``gravity`` section's own bodies and bias). `PayloadSelector.update` runs in every cycle, before the
gravity compensation:

* a new index that names a set starts a switch: one log line (old -> new index, name and mass), then
  the payload moves from the values in use to the new set's over ``gravity.switch_ramp_s``,

      p(s) = p_from + s (p_to - p_from),    s = min(1, elapsed / switch_ramp_s),   p = [m, m c, b],

  into the gravity compensation (`GravityCompensator.carry`) and the static torque of the effects at
  the total torque (`FastPredictor.carry_payload`). Both are linear in m, m c and b, so this blends the
  gravity term and tau_s exactly: the wrench moves by (p_to - p_from)/ramp per second, never in a step.
  ``payload_active`` (`active`) names the new set once the ramp has ended; until then the old one.
* a new index that names no set is refused: the fault ``payload_invalid`` latches (the correction
  ramps to zero: with the mounted tool unknown the wrench is not trusted), the set in use stays, and
  exactly one line is logged (while the fault stays latched, at most ``QUIET_AFTER`` further refusals
  are). While ``payload_index`` still names no set the fault trips again after each reset; a reset with
  a valid index (the one in use or another, which then switches) clears it.

`reload` is the entry point for a new ``gravity`` section at run time (a reload of the YAML): it may be
called from another thread; the cycle takes the new table at its next update and treats the PLC's
index as newly written: a set in use whose values changed ramps to its new values, a set that is gone
is refused as above. ``gravity.g_mps2`` is not part of a switch (it changes the arm's own static torque
too): a change of it needs a restart.
"""

from __future__ import annotations

import logging

from plc_link.contract import Fault

from .compensation import FastPredictor
from .faults import FaultMonitor
from .gravity import GravityCompensator, GravityConfig, PayloadSet

log = logging.getLogger("stiffcomp.payload")
QUIET_AFTER = 10        # refusals logged while payload_invalid stays latched (the first is the fault's own line)


def _vector(p: PayloadSet) -> list[float]:
    """[m, m c, b]: the ten numbers a switch blends (kg, kg m, N and Nm)."""
    return [p.mass_kg, *p.mc, *p.bias]


def describe(p: PayloadSet) -> str:
    """The set in words, for log lines: ``3 'spindle + D20 mill' (12.5 kg)``, with its TCP if it records one."""
    tcp = "" if p.tcp_mm is None else f", TCP [{', '.join(f'{v:g}' for v in p.tcp_mm)}] mm"
    return f"{p.index} {p.name!r} ({p.mass_kg:g} kg{tcp})"


class PayloadSelector:
    """The payload set in use and the switch between sets.

    Parameters
    ----------
    sets : every selectable set by index (`GravityConfig.payload_sets`), with index 0
    ramp_s : the switch ramp, s (0: the next cycle)
    gravity, predictor : where the payload goes
    faults : where a missing index trips ``payload_invalid``
    """

    def __init__(self, sets: dict[int, PayloadSet], ramp_s: float, gravity: GravityCompensator,
                 predictor: FastPredictor, faults: FaultMonitor):
        self.sets = sets
        self.ramp_s = float(ramp_s)
        self.gravity = gravity
        self.predictor = predictor
        self.faults = faults
        self.active = sets[0]                   # the set in effect; during a ramp the one switched from
        self.target: PayloadSet | None = None   # the set a ramp moves to
        self.requested = 0                      # the PLC's last payload_index
        self.switches = 0
        self._now = _vector(self.active)        # the blended values in use
        self._from = self._to = self._now
        self._elapsed = 0.0
        self._refused: str | None = None        # the fault message while the requested index names no set
        self._lines = 0                         # refusals logged since the fault latched
        self._pending: tuple[dict[int, PayloadSet], float] | None = None
        self._apply()

    @classmethod
    def from_config(cls, section: GravityConfig, gravity: GravityCompensator, predictor: FastPredictor,
                    faults: FaultMonitor) -> PayloadSelector:
        """From the ``gravity`` section: its table and ``switch_ramp_s``."""
        return cls(section.payload_sets(), section.switch_ramp_s, gravity, predictor, faults)

    @classmethod
    def only(cls, gravity: GravityCompensator, predictor: FastPredictor, faults: FaultMonitor) -> PayloadSelector:
        """A table of one set, index 0: the payload ``gravity`` holds."""
        p = PayloadSet(0, "gravity bodies", gravity.mass, tuple(gravity.mc.tolist()), tuple(gravity.bias.tolist()), None)
        return cls({0: p}, 0.0, gravity, predictor, faults)

    def reload(self, section: GravityConfig) -> None:
        """Take a new ``gravity`` section's table and ramp at the next cycle (safe from another thread:
        the pair is replaced whole). The section's ``g_mps2`` is not applied (a restart changes it)."""
        self._pending = (section.payload_sets(), section.switch_ramp_s)

    def update(self, dt: float, requested: int) -> bool:
        """One cycle of ``dt`` seconds with the PLC's ``payload_index`` = ``requested``; True when the payload
        in use moved (a ramp's step)."""
        if self._pending is not None:
            (self.sets, self.ramp_s), self._pending = self._pending, None
            self._request(requested, "reload")
        elif requested != self.requested:
            self._request(requested, "payload_index")
        if self._refused is not None:
            self.faults.trip(Fault.PAYLOAD_INVALID, self._refused)      # again after a reset: the cause persists
        if self.target is None:
            return False
        self._ramp(dt)
        return True

    @property
    def quiet(self) -> bool:
        """Nothing under way: no switch ramping, no refused index, no new table waiting (`update` then changes
        nothing while the PLC's index stays `requested`)."""
        return self._pending is None and self._refused is None and self.target is None

    @property
    def destination(self) -> PayloadSet:
        """The set the payload is at or moving to."""
        return self.target if self.target is not None else self.active

    def _request(self, index: int, why: str) -> None:
        self.requested = index
        new = self.sets.get(index)
        if new is None:
            self._refuse(index)
            return
        self._refused = None
        if new.index == self.destination.index and _vector(new) == self._to:    # nothing to move
            if self.target is None:
                self.active = new               # (a reload may have renamed it)
            else:
                self.target = new
            return
        old = self.destination
        log.info("payload switch (%s): %s -> %s over gravity.switch_ramp_s = %g s", why, describe(old),
                 describe(new), self.ramp_s)
        self.switches += 1
        self.target = new
        self._from, self._to, self._elapsed = self._now, _vector(new), 0.0

    def _refuse(self, index: int) -> None:
        self._refused = (f"payload_index = {index} names no payload set (gravity.payloads has "
                         f"{', '.join(str(k) for k in sorted(self.sets))}); set {describe(self.destination)} "
                         "stays in use")
        if not self.faults.word & Fault.PAYLOAD_INVALID:    # the trip in this cycle logs it
            self._lines = 0
            return
        self._lines += 1                # latched already, so the trip would not log it: this line does
        if self._lines <= QUIET_AFTER:   # a PLC cycling through bad indices must not fill the disk
            log.error("fault payload_invalid: %s%s", self._refused, "; further refusals are not logged until a "
                      "reset" if self._lines == QUIET_AFTER else "")

    def _ramp(self, dt: float) -> None:
        self._elapsed += dt
        # a ramp of N periods ends in its Nth cycle, whatever the rounding of the summed periods
        s = 1.0 if self._elapsed >= self.ramp_s - 1e-9 else self._elapsed / self.ramp_s
        if s >= 1.0:
            self._now = self._to
            self.active, self.target = self.target, None
        else:
            self._now = [a + s * (b - a) for a, b in zip(self._from, self._to)]
        self._apply()

    def _apply(self) -> None:
        m, cx, cy, cz, *bias = self._now
        self.gravity.carry(m, (cx, cy, cz), bias)
        self.predictor.carry_payload(m, (cx, cy, cz))
