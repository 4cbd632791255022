"""The robot's sessions as the road keeps them: a named life cycle, and what one session remembers.

A session begins with a packet taken after nothing (the service's start), after a silence, or after the robot's
stamp fell back (its program started the interface again). Its answers ramp in from zero; then the road answers
with the whole correction until the robot falls silent:

    AWAITING ──packet──▶ RAMPING ──ramp_s──▶ ANSWERING ──silence_s──▶ SILENT ──packet──▶ RAMPING
                            ▲                     │
                            └──stamp fell back────┘
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field


class Phase(enum.Enum):
    """Where the road stands with the robot."""

    AWAITING = "awaiting"        # no packet taken since the service started
    RAMPING = "ramping"          # a session began less than ramp_s ago: its answers ramp in from zero
    ANSWERING = "answering"      # the whole correction is answered
    SILENT = "silent"            # no packet taken for silence_s: the next one begins a new session


@dataclass
class Session:
    """One session of the robot's: from the packet that began it on."""

    began: float = 0.0                  # when its first packet came (s, the road's clock): the ramp counts from it
    stamp: int | None = None            # the last stamp taken
    late: int | None = None             # the robot's own count of late answers in its last packet, if it sends one
    steps: list[int] = field(default_factory=list)     # its first stamp steps (the robot's own cycle)
    said_kept_faults: bool = False      # the warning about faults its return does not reset was given


@dataclass
class Sessions:
    """The road's sessions with the robot and when it was last heard.

    Attributes
    ----------
    silence_s : a packet after this long without one taken begins a new session
    ramp_s : a session's answers ramp in from zero over this long
    """

    silence_s: float
    ramp_s: float
    current: Session = field(default_factory=Session)
    count: int = 0                      # sessions begun
    restarts: int = 0                   # of them, begun by a stamp that fell back
    last_t: float | None = None         # the last packet taken (any session)
    heard_t: float | None = None        # the last packet from the robot's address, taken or not

    def phase(self, now: float) -> Phase:
        """The road's phase at ``now`` (module docstring)."""
        if self.last_t is None:
            return Phase.AWAITING
        if now - self.last_t > self.silence_s:
            return Phase.SILENT
        return Phase.RAMPING if now - self.current.began < self.ramp_s else Phase.ANSWERING

    def ramp(self, now: float) -> float:
        """The share of the correction a session's answer carries at ``now``: 0 at its first packet, 1 after
        ``ramp_s``."""
        return min(1.0, (now - self.current.began) / self.ramp_s) if self.ramp_s > 0 else 1.0

    def begin(self, now: float, restarted: bool) -> Session:
        """A new session from the packet taken at ``now``."""
        self.count += 1
        self.restarts += int(restarted)
        self.current = Session(began=now)
        return self.current
