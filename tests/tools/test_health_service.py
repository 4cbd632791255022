"""`stiffcomp health` against a real `stiffcomp run`: 0 while it runs, 1 with the reason once the
sensor replay stops (a short log, not looped, ends in a sensor_timeout fault); `--live` stays 0, over
HTTP and over Modbus.
"""

from __future__ import annotations

import signal
import subprocess
import sys
import time

import pytest
import yaml

from hil.testing import ROOT, constant_log, free_port, wait_for_port, write_config
from tools.cli import main
from tools.health_cmd import check

pytestmark = pytest.mark.realtime


def poll_health(port: int, want: bool, timeout_s: float) -> tuple[bool, str]:
    deadline = time.monotonic() + timeout_s
    healthy, reason = check("127.0.0.1", port)
    while healthy != want and time.monotonic() < deadline:
        time.sleep(0.2)
        healthy, reason = check("127.0.0.1", port)
    return healthy, reason


def test_health_is_0_while_running_and_1_when_the_sensor_falls_silent(tmp_path, capsys):
    port, http = free_port(), free_port()
    log = constant_log(tmp_path / "short.csv", [10.0, 0.0, -50.0, 0.0, 1.0, 0.0], seconds=3.0)
    # no exceed bound: this machine's timing must not decide the test
    cfg = write_config(tmp_path, {"plc": {"port": port}, "monitoring": {"port": http, "health_max_exceed_rate": 1.0},
                                  "cycle": {"stats_log_interval_s": 0},
                                  "source": {"replay": {"file": str(log), "loop": False}}})
    service = subprocess.Popen([sys.executable, "-m", "tools.cli", "run", "--config", str(cfg)], cwd=ROOT,
                               stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        wait_for_port(port, service)
        healthy, reason = poll_health(http, True, 2.0)
        assert healthy, reason
        p = subprocess.run([sys.executable, "-m", "tools.cli", "health", "--config", str(cfg)], cwd=ROOT,
                           check=False, capture_output=True, text=True, timeout=30)
        assert p.returncode == 0 and p.stdout.startswith("healthy: ")
        healthy, reason = poll_health(http, False, 10.0)        # the 3 s log ends: sensor_timeout
        assert not healthy and "sensor_timeout" in reason
        p = subprocess.run([sys.executable, "-m", "tools.cli", "health", "--config", str(cfg)], cwd=ROOT,
                           check=False, capture_output=True, text=True, timeout=30)
        assert p.returncode == 1 and "sensor_timeout" in p.stdout and p.stdout.count("\n") == 1
        # the task still cycles: live, over HTTP and, for a config without HTTP, over Modbus
        assert main(["health", "--live", "--config", str(cfg)]) == 0
        modbus_only = tmp_path / "modbus_only.yaml"
        modbus_only.write_text(yaml.safe_dump({"monitoring": {"enabled": False}, "plc": {"port": port}}))
        assert main(["health", "--live", "--config", str(modbus_only)]) == 0
        assert main(["health", "--config", str(modbus_only)]) == 1
        out = capsys.readouterr().out.splitlines()
        assert out[0].startswith("live: ") and out[1].startswith("live: ") and out[1].endswith(f"(Modbus 127.0.0.1:{port})")
        assert out[2].startswith("unhealthy: fault word 0x0001: sensor_timeout")
    finally:
        service.send_signal(signal.SIGTERM)
        service.wait(timeout=15)
