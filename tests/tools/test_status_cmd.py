"""`stiffcomp status --watch` under a pseudo-terminal, against a real running service.

The terminal's screen is rebuilt with pyte (a VT100 emulator) from what the command writes, so the
test reads what a person would see: the cycle count rising, the task state, a fault spelt out.
"""

from __future__ import annotations

import fcntl
import os
import pty
import re
import select
import signal
import struct
import subprocess
import sys
import termios
import time

import numpy as np
import pyte
import pytest

from hil.testing import constant_log, free_port, wait_for_port, write_config
from service.app import Service
from service.config import load_config
from testlib.common import wait_for
from tools.cli import main
from tools.status_cmd import reader_for

pytestmark = pytest.mark.realtime

COLS, ROWS = 110, 40
CLI = [sys.executable, "-m", "tools.cli"]


class Terminal:
    """A command on a pseudo-terminal of COLS x ROWS, its screen emulated by pyte."""

    def __init__(self, argv: list[str]):
        master, slave = pty.openpty()
        fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", ROWS, COLS, 0, 0))
        env = {**os.environ, "TERM": "xterm-256color"}
        env.pop("COLUMNS", None), env.pop("LINES", None)
        self.proc = subprocess.Popen(argv, stdin=slave, stdout=slave, stderr=slave, env=env)
        os.close(slave)
        self.master = master
        self.screen = pyte.Screen(COLS, ROWS)
        self.stream = pyte.ByteStream(self.screen)

    def text(self) -> str:
        return "\n".join(self.screen.display)

    def wait_for(self, predicate, timeout_s: float = 20.0) -> str:
        """The screen's text once ``predicate(text)`` holds; AssertionError with the screen if it never does."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if predicate(self.text()):
                return self.text()
            if select.select([self.master], [], [], 0.1)[0]:
                try:
                    self.stream.feed(os.read(self.master, 65536))
                except OSError:          # the command exited and closed the terminal
                    break
        raise AssertionError("the screen never showed what was expected:\n" + self.text())

    def close(self) -> int:
        if self.proc.poll() is None:
            self.proc.send_signal(signal.SIGTERM)
        try:
            while select.select([self.master], [], [], 0.1)[0] and os.read(self.master, 65536):
                pass                       # drain, so the command never blocks on a full terminal
        except OSError:
            pass
        code = self.proc.wait(timeout=10)
        os.close(self.master)
        return code


def cycles(text: str) -> int | None:
    m = re.search(r"cycles\s+(\d+)", text)
    return int(m.group(1)) if m else None


def test_watch_shows_live_values_and_spells_out_a_fault(tmp_path):
    port = free_port()
    log = constant_log(tmp_path / "short.csv", [10.0, 0.0, -50.0, 0.0, 1.0, 0.0], seconds=3.0)
    cfg = write_config(tmp_path, {"plc": {"port": port}, "monitoring": {"port": free_port()},
                                  "cycle": {"stats_log_interval_s": 0},
                                  "source": {"replay": {"file": str(log), "loop": False}}})
    service = subprocess.Popen([*CLI, "run", "--config", str(cfg)], stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    term = None
    try:
        wait_for_port(port, service)
        term = Terminal([*CLI, "status", "--watch", "--config", str(cfg)])
        # A read of the terminal may end halfway through a redraw, so each step waits for one screen
        # that shows everything it judges together, never judging part of a frame.
        rows = [f"q{i}" for i in range(1, 7)]
        first = term.wait_for(lambda t: "RUN" in t and (cycles(t) or 0) > 0 and f"modbus 127.0.0.1:{port}" in t
                              and all(r in t for r in rows) and "fz" in t and "dz" in t)
        n1 = cycles(first)
        # live: the count rises, with the rate and the exec percentiles
        rate, exec_ = re.compile(r"rate [\d,]+ /s"), re.compile(r"p50 \d+ us\s+p99 \d+ us")
        term.wait_for(lambda t: (cycles(t) or 0) > n1 and rate.search(t) and exec_.search(t))
        # the log ends after 3 s and is not looped: the sensor falls silent, the fault is spelt out
        fault = re.compile(r"0x0001\s+sensor_timeout")
        term.wait_for(lambda t: fault.search(t) and "faulted" in t)
        assert term.close() == 0                                        # SIGTERM ends the view cleanly
    finally:
        if term is not None and term.proc.poll() is None:
            term.close()
        service.send_signal(signal.SIGTERM)
        service.wait(timeout=15)


def test_once_without_a_service_exits_1_naming_the_address(tmp_path, capsys):
    port = free_port()
    cfg = write_config(tmp_path, {"plc": {"port": port}})
    assert main(["status", "--config", str(cfg)]) == 1
    assert f"no answer from the service at 127.0.0.1:{port}" in capsys.readouterr().err


LIVE = {"heartbeat", "cycle_count", "exceed_count", "last_exec_us", "period_jitter_us", "cycle_exceeded",
        "sensor_samples", "sample_age_ms"}                  # registers that change from cycle to cycle


def test_ads_and_modbus_readings_agree_by_name(tmp_path):
    """The same service read both ways: every register that holds still between the two reads agrees
    (to float32, the registers' type), and the live counters only move forward."""
    log = constant_log(tmp_path / "w.csv", [40.0, -20.0, 120.0, 3.0, -1.0, 0.5], seconds=1.0)
    cfg_path = write_config(tmp_path, {"plc": {"port": free_port(), "enable_on_start": True},
                                       "source": {"replay": {"file": str(log)}},
                                       "faults": {"overrun_trip_count": 1000, "plc_heartbeat_timeout_ms": 0}})
    cfg = load_config(cfg_path)
    s = Service(cfg)
    s.start()
    modbus, _ = reader_for(cfg, "modbus", None, None)
    ads, _ = reader_for(cfg, "ads", None, None)
    try:
        time.sleep(1.5)                     # the correction ramps in and holds; the filter has settled
        m = modbus.read()
        a = ads.read()
        m2 = modbus.read()
    finally:
        modbus.close(), ads.close()
        s.stop()
    assert set(a) == set(m) == set(s.rmap.codecs["to_plc"].names)
    steady = [n for n in m if n not in LIVE and m[n] == m2[n]]
    assert {"status_word", "task_state", "correction_q2", "wrench_fz", "deflection_dx"} <= set(steady)
    assert abs(m["correction_q2"]) > 1e-4                   # the correction is active, not all zeros
    for n in steady:
        assert np.float32(a[n]) == np.float32(m[n]), n
    assert m["cycle_count"] <= a["cycle_count"] <= m2["cycle_count"]


def test_status_reads_over_ads_when_the_service_serves_no_modbus(tmp_path, capsys):
    ads_port = free_port()
    cfg = write_config(tmp_path, {"plc": {"role": "none", "port": free_port()}, "ads": {"port": ads_port}})
    service = subprocess.Popen([*CLI, "run", "--config", str(cfg)], stdout=subprocess.DEVNULL,
                               stderr=subprocess.DEVNULL)
    try:
        wait_for_port(ads_port, service)
        # the ADS port answers while the cycle may not have run yet (a loaded machine): ask until it has
        outs = []

        def ran() -> bool:
            assert main(["status", "--config", str(cfg)]) == 0
            outs.append(capsys.readouterr().out)
            return (cycles(outs[-1]) or 0) > 0

        assert wait_for(ran, timeout=60.0, every=0.2), outs[-1]
        out = outs[-1]
        assert f"ads 127.0.0.1:{ads_port}" in out and "RUN" in out
        assert re.search(r"rate [\d,]+ /s", out) and all(f"q{i}" in out for i in range(1, 7))
    finally:
        service.send_signal(signal.SIGTERM)
        service.wait(timeout=15)
    # the service is gone: the same command names the address it tried, exit 1
    assert main(["status", "--config", str(cfg)]) == 1
    assert f"no answer from the service over ADS: no ADS server at 127.0.0.1:{ads_port}" in capsys.readouterr().err


def test_a_config_serving_neither_protocol_names_both_keys(tmp_path, capsys):
    cfg = write_config(tmp_path, {"plc": {"role": "client"}, "ads": {"enabled": False}})
    assert main(["status", "--config", str(cfg)]) == 2
    err = capsys.readouterr().err
    assert str(cfg) in err and "plc.role is client" in err and "ads.enabled is false" in err
