"""Rate-limited logging of protocol errors: one line per client and reason per interval, with a count.

A client that sends garbage must not fill the disk (pymodbus' hex dump per bad frame wrote 20 MB for
5,000 frames). `RateLimitedLog.report` counts every event; the first of a (client, reason) pair is
logged at once, later ones are folded into one line per interval that says how many there were.
Shared by the Modbus and ADS servers.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable


class RateLimitedLog:
    """Count protocol errors per (client, reason) and log each pair at most once per ``interval_s``.

    Parameters
    ----------
    logger : where the lines go
    interval_s : s, the shortest time between two lines of one (client, reason) pair
    max_keys : pairs tracked at once; beyond it new pairs are counted under ("*", "other reasons"),
        so a flood of distinct clients cannot grow memory without bound
    clock : monotonic seconds (a parameter so tests can drive it)
    level : logging level of the lines
    """

    def __init__(self, logger: logging.Logger, interval_s: float = 10.0, max_keys: int = 256,
                 clock: Callable[[], float] = time.monotonic, level: int = logging.WARNING):
        self.logger, self.interval_s, self.max_keys = logger, interval_s, max_keys
        self.clock, self.level = clock, level
        self._pending: dict[tuple[str, str], int] = {}     # counted since the last line
        self._last: dict[tuple[str, str], float] = {}      # when the last line was written
        self.total = 0

    def report(self, client: str, reason: str, detail: str = "") -> None:
        """Count one event; write a line if this pair has had none for ``interval_s``."""
        self.total += 1
        key = (client, reason)
        if key not in self._last and len(self._last) >= self.max_keys:
            self._expire()
            if len(self._last) >= self.max_keys:
                key, detail = ("*", "other reasons"), ""
        self._pending[key] = self._pending.get(key, 0) + 1
        now = self.clock()
        if now - self._last.get(key, -float("inf")) >= self.interval_s:
            self._emit(key, now, detail)

    def flush(self) -> None:
        """Write the counts not yet written (on shutdown)."""
        now = self.clock()
        for key in [k for k, n in self._pending.items() if n]:
            self._emit(key, now, "")

    def _emit(self, key: tuple[str, str], now: float, detail: str) -> None:
        n = self._pending.pop(key, 0)
        since = self._last.get(key)
        self._last[key] = now
        if n:
            span = "first report" if since is None else f"in the last {now - since:.0f} s"
            tail = f" ({detail})" if detail else ""
            self.logger.log(self.level, "%s: %s: %d time(s), %s%s", key[0], key[1], n, span, tail)

    def _expire(self) -> None:
        """Forget pairs quiet for a whole interval (their counts are written first)."""
        now = self.clock()
        for key, t in list(self._last.items()):
            if now - t >= self.interval_s:
                if self._pending.get(key):
                    self._emit(key, now, "")
                del self._last[key]
