"""RateLimitedLog: one line per client and reason per interval, with the count of what it folded."""

from __future__ import annotations

import logging

from io_base.ratelog import RateLimitedLog


class Clock:
    def __init__(self):
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def make(caplog, **kw):
    clock = Clock()
    caplog.set_level(logging.WARNING, logger="test.ratelog")
    return RateLimitedLog(logging.getLogger("test.ratelog"), interval_s=10.0, clock=clock, **kw), clock


def test_a_flood_of_one_reason_is_one_line_per_interval_with_its_count(caplog):
    rl, clock = make(caplog)
    for _ in range(1000):
        rl.report("10.0.0.1", "short header")
    assert len(caplog.records) == 1 and "1 time(s)" in caplog.records[0].getMessage()
    clock.t = 10.0
    rl.report("10.0.0.1", "short header")
    assert len(caplog.records) == 2 and "1000 time(s)" in caplog.records[1].getMessage()
    rl.report("10.0.0.1", "short header")
    rl.flush()
    assert len(caplog.records) == 3 and "1 time(s)" in caplog.records[2].getMessage()
    assert rl.total == 1002


def test_clients_and_reasons_are_counted_apart_and_bounded(caplog):
    rl, _ = make(caplog, max_keys=4)
    for i in range(100):
        rl.report(f"10.0.0.{i}", "bad length")
    rl.flush()
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) <= 6                  # 4 clients, then the "other reasons" bucket: its first and its flush
    assert sum(int(m.split(": ")[2].split(" ")[0]) for m in lines) == 100       # nothing uncounted
