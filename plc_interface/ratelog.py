"""Protocol errors logged rate-limited: one line per client and reason per interval, with a count.

A client that sends thousands of bad frames must not fill the log (pymodbus alone wrote 20 MB of hex
dumps for 5,000 frames); what a person needs is who, why, how often, and one example.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable


class RateLimitedLog:
    """Count protocol errors per (client, reason); log the first at once and then one line per interval.

    Parameters
    ----------
    logger : logging.Logger
    interval_s : float
        At most one line per client and reason in this time.
    clock : callable () -> float
    """

    def __init__(self, logger: logging.Logger, interval_s: float = 10.0,
                 clock: Callable[[], float] = time.monotonic):
        self.log = logger
        self.interval = float(interval_s)
        self.clock = clock
        self._seen: dict[tuple[str, str], list] = {}     # key -> [last line time, count since, total]
        self.total = 0

    def report(self, client: str, reason: str, example: str = "") -> None:
        """Count one error; log it if this client and reason have not been logged within the interval."""
        self.total += 1
        now = self.clock()
        entry = self._seen.get((client, reason))
        if entry is None:
            if len(self._seen) > 10_000:            # a flood of distinct clients must not grow without bound
                self._seen.clear()
            self._seen[(client, reason)] = [now, 0, 1]
            self.log.warning("%s: %s%s", client, reason, f" ({example})" if example else "")
            return
        entry[1] += 1
        entry[2] += 1
        if now - entry[0] >= self.interval:
            self.log.warning("%s: %s, %d more time(s) in the last %.0f s (%d in all)%s", client, reason, entry[1],
                             now - entry[0], entry[2], f"; e.g. {example}" if example else "")
            entry[0], entry[1] = now, 0

    def counts(self) -> dict[tuple[str, str], int]:
        """Total per (client, reason)."""
        return {k: v[2] for k, v in self._seen.items()}
