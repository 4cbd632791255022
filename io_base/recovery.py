"""The reset bit a peer raises when its link to the service comes back: the PLC after a lost Modbus link, the
robot road after the robot's silence.

The peer raises the bit at once and holds it while the service's fault word still shows a fault, for `HOLD_S`
at most: a one-cycle pulse could fall between two cycles of a service that a loaded host stalls for longer than
the peer's cycle. A reset clears only the faults whose cause is gone (`service.supervision`); ``clears`` narrows
it further to the faults the peer may acknowledge by itself: with other faults latched the bit is not raised,
and they wait for someone who can see them (a PLC's program, the robot's own command word, a restart).
"""

from __future__ import annotations

HOLD_S = 0.25


class RecoveryReset:
    """Parameters
    ----------
    hold_s : how long after the recovery the bit is held while faults remain (s)
    clears : the fault bits the peer acknowledges by itself (all by default)
    """

    def __init__(self, hold_s: float = HOLD_S, clears: int = 0xFFFF):
        self.hold_s = float(hold_s)
        self.clears = int(clears)
        self._since: float | None = None

    def recovered(self, t: float) -> None:
        """The link came back at ``t`` (s); a peer's first contact counts as one."""
        self._since = t

    def bit(self, t: float, fault_word: int) -> bool:
        """Whether the reset bit is raised at ``t`` with the service's ``fault_word``."""
        if self._since is None or t - self._since > self.hold_s or int(fault_word) & ~self.clears & 0xFFFF:
            return False
        return t == self._since or int(fault_word) != 0
