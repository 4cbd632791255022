"""What the road counts and reports: typed here, a plain dict only where the I/O server's statistics leave the
process as JSON (`RoadStats.as_dict`)."""

from __future__ import annotations

from dataclasses import dataclass, field

from .session import Phase

LATENCY_RING = 1 << 16          # the answers whose latency the report's percentiles are over


@dataclass
class RoadCounts:
    """The road's counts since it started."""

    packets: int = 0                    # datagrams received
    answered: int = 0
    late_reported: int = 0              # answers the robot reports it did not take in time
    stamp_gaps: int = 0                 # packets the stamps say never came
    slow_answers: int = 0               # answers sent later than the robot's cycle after their packet
    dropped: dict[str, int] = field(default_factory=dict)     # by reason


@dataclass(frozen=True)
class RoadStats:
    """What the road reports: its counts, its sessions, the robot's cycle as its stamps say, the interface's own
    checks, and the answers' latency (us: p50, p99, max over the last `LATENCY_RING` answers, and how many)."""

    interface: str
    counts: RoadCounts
    sessions: int
    restarts: int
    phase: Phase
    cycle_seen_ms: float | None
    checks: dict
    latency_us: dict

    def as_dict(self) -> dict:
        """As the service's final statistics print it (JSON)."""
        c = self.counts
        return {"interface": self.interface, "packets": c.packets, "answered": c.answered, "sessions": self.sessions,
                "restarts": self.restarts, "late_reported": c.late_reported, "stamp_gaps": c.stamp_gaps,
                "slow_answers": c.slow_answers, "dropped": dict(c.dropped), "phase": self.phase.value,
                "cycle_seen_ms": self.cycle_seen_ms, **self.checks, "latency_us": dict(self.latency_us)}
