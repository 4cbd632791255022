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

import pyte

from hil.testing import constant_log, free_port, wait_for_port, write_config
from tools.cli import main

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
