"""Health from the I/O process: healthy while the service runs clean; not, with the reason, once the
sensor replay ends (a fault) or the service stops."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request

from hil.testing import constant_log, free_port, write_config
from service.app import Service
from service.config import load_config


def health(port: int) -> tuple[int, dict]:
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}/health", timeout=1.0) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def wait_for_status(port: int, status: int, timeout: float = 20.0) -> dict | None:
    """The first health answer with HTTP ``status`` within ``timeout`` s (a guard, not a timing check)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        code, body = health(port)
        if code == status:
            return body
        time.sleep(0.05)
    return None


def test_health_follows_the_task_and_its_faults(tmp_path):
    port = free_port()
    log = constant_log(tmp_path / "short.blf", [100.0, 0.0, 200.0, 0.0, 0.0, 0.0], seconds=3.0)
    cfg = load_config(write_config(tmp_path, {
        "monitoring": {"port": port, "health_max_exceed_rate": 0.5},      # a loaded CI host skips deadlines
        "source": {"replay": {"file": str(log), "loop": False}},
        "faults": {"overrun_trip_count": 1000}}))
    s = Service(cfg)
    s.start()
    try:
        ok = wait_for_status(port, 200)
        assert ok is not None and ok["healthy"] is True and ok["cycle_count"] > 0
        # the replay ends after 3 s: the sensor falls silent, sensor_timeout latches, health says so
        bad = wait_for_status(port, 503)
        assert bad is not None and bad["healthy"] is False
        assert "sensor_timeout" in bad["reason"] and "sensor_timeout" in bad["faults"]
    finally:
        s.stop()
