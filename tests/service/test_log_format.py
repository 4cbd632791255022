"""`--log-format json`: every line a JSON object; the service logs state changes, not cycles."""

from __future__ import annotations

import json
import logging
import subprocess
import sys

import pytest

from hil.testing import ROOT, free_port, write_config
from io_base.log_format import JsonFormatter

pytestmark = pytest.mark.realtime


def test_a_record_becomes_one_json_line_with_its_extra_fields():
    log = logging.getLogger("stiffcomp.test")
    record = log.makeRecord(log.name, logging.WARNING, __file__, 1, "fault %s:\n%s", ("overrun", "10 late"),
                            None, extra={"fault_word": 64, "joint": "q3"})
    line = JsonFormatter().format(record)
    assert "\n" not in line
    d = json.loads(line)
    assert d["level"] == "WARNING" and d["logger"] == "stiffcomp.test"
    assert d["message"] == "fault overrun:\n10 late"
    assert d["fault_word"] == 64 and d["joint"] == "q3"
    assert d["time"].endswith("+00:00")
    assert "args" not in d and "msg" not in d


def test_run_with_json_logs_one_line_per_state_change(tmp_path):
    cfg = write_config(tmp_path, {"plc": {"port": free_port()}, "monitoring": {"port": free_port()},
                                  "cycle": {"stats_log_interval_s": 0.5}})
    p = subprocess.run([sys.executable, "-m", "tools.cli", "run", "--config", str(cfg), "--duration", "2",
                        "--log-format", "json"], cwd=ROOT, check=False, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    lines = [json.loads(x) for x in p.stderr.splitlines()]     # every line parses
    messages = [d["message"] for d in lines]
    assert any(m.startswith("service running") for m in messages)
    assert any(m.startswith("service stopped after") for m in messages)
    cycles = int(next(m for m in messages if m.startswith("service stopped after")).split()[3])
    assert cycles > 100
    # start, stop, and the task info every 0.5 s: a handful of lines for a thousand-odd cycles
    assert len(lines) < 20, messages
    assert all({"time", "level", "logger", "message"} <= set(d) for d in lines)
