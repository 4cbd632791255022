"""The two processes watch each other, and no signal drops the correction without the ramp (issue 17, item 4).

Against the running service (`stiffcomp run` in a child process): kill -9 of the I/O process is logged,
latches io_process and is restarted (Modbus answers again within 5 s) or, with ``faults.io_restarts: 0``,
ends the service with exit code 1 within 5 s; kill -9 of the cycle process makes the I/O process log it
and exit 1; SIGHUP reloads the config and leaves the service running; Ctrl-C to the process group prints no traceback.
"""

from __future__ import annotations

import ctypes
import json
import os
import signal
import time
from pathlib import Path

import pytest
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

from hil.run import HilError, ServiceProcess
from hil.testing import ROOT, free_port, write_config
from plc_link.contract import Fault, Status
from plc_link.register_map import RegisterMap

pytestmark = pytest.mark.realtime

RMAP = RegisterMap.from_yaml(ROOT / "config" / "registers.yaml")
CODEC = RMAP.codecs["to_plc"]
PR_SET_CHILD_SUBREAPER = 36


class Running:
    """`stiffcomp run` in a child process (`hil.run.ServiceProcess`: its log in a file, ready when its
    /health reports the task running); stopped and reaped on every path."""

    def __init__(self, tmp_path: Path, overrides: dict | None = None, new_session: bool = False):
        self.port = free_port()
        cfg = write_config(tmp_path, {"plc": {"port": self.port}, **(overrides or {})})
        self.service = ServiceProcess(cfg, tmp_path, new_session=new_session)
        self.p, self.stats, self.log = self.service.proc, self.service.stats, self.service.log_path
        try:
            self.service.wait_running(60)
        except HilError:
            self.close()
            raise

    def text(self) -> str:
        return self.log.read_text()

    def io_pid(self) -> int:
        """The I/O process: the child that multiprocessing spawned (not its resource tracker)."""
        kids = Path(f"/proc/{self.p.pid}/task/{self.p.pid}/children").read_text().split()
        io = [int(k) for k in kids if b"spawn_main" in Path(f"/proc/{k}/cmdline").read_bytes()]
        assert len(io) == 1, kids
        return io[0]

    def read(self) -> dict[str, float] | None:
        """The to_plc block by name over Modbus, or None when nothing answers."""
        with ModbusTcpClient("127.0.0.1", port=self.port, timeout=0.3, retries=0) as c:
            try:
                if not c.connect():
                    return None
                r = c.read_input_registers(CODEC.start, count=CODEC.words)
            except (OSError, ModbusException):     # the I/O process died under this request
                return None
            return None if r.isError() else dict(zip(CODEC.names, CODEC.decode(r.registers)))

    def stop(self) -> int:
        """SIGTERM, then the exit code."""
        self.p.send_signal(signal.SIGTERM)
        return self.wait()

    def wait(self, timeout: float = 30.0) -> int:
        try:
            return self.p.wait(timeout)
        finally:
            self.close()

    def close(self) -> None:
        self.service.stop()


def until(condition, timeout: float, what: str):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if got := condition():
            return got
        time.sleep(0.05)
    raise AssertionError(f"not within {timeout:g} s: {what}")


@pytest.fixture
def service(tmp_path):
    made = []

    def start(**kw) -> Running:
        made.append(Running(tmp_path, **kw))
        return made[-1]

    yield start
    for s in made:
        s.close()


def test_io_process_killed_is_restarted_and_serves_modbus_within_5s(service):
    svc = service()
    assert svc.read() is not None
    io = svc.io_pid()
    t_kill = time.monotonic()
    os.kill(io, signal.SIGKILL)
    values = until(lambda: (v := svc.read()) is not None and v, 5.0, "Modbus answers again")
    assert time.monotonic() - t_kill < 5.0
    assert svc.io_pid() != io
    # the PLC sees why: io_process latched, no correction applied
    assert int(values["fault_word"]) & Fault.IO_PROCESS and int(values["status_word"]) & Status.FAULTED
    assert not int(values["status_word"]) & Status.ACTIVE
    log = svc.text()
    assert f"the I/O process (pid {io}) died (killed by SIGKILL)" in log and "fault io_process" in log
    assert "restarting the I/O process (1 of faults.io_restarts = 3)" in log
    assert svc.stop() == 0
    stats = json.loads(svc.stats.read_text())
    assert stats["status"] == "stopped" and stats["failure"] is None
    assert stats["io_process"] == {"deaths": ["killed by SIGKILL"], "restarts": 1}


def test_io_process_killed_without_restarts_stops_the_service_with_exit_1_within_5s(service):
    svc = service(overrides={"faults": {"io_restarts": 0}})
    os.kill(svc.io_pid(), signal.SIGKILL)
    t_kill = time.monotonic()
    until(lambda: svc.p.poll() is not None, 5.0, "the service exits")
    assert time.monotonic() - t_kill < 5.0
    assert svc.wait() == 1
    stats = json.loads(svc.stats.read_text())
    assert stats["status"] == "stopped" and "faults.io_restarts = 0" in stats["failure"]
    assert stats["io_process"]["deaths"] == ["killed by SIGKILL"]
    assert "the service stops (exit code 1)" in svc.text()


def test_cycle_process_killed_the_io_process_logs_it_and_exits_1(service):
    """The I/O process is reparented to this test (a child subreaper), which reaps it and reads its code."""
    libc = ctypes.CDLL(None, use_errno=True)
    assert libc.prctl(PR_SET_CHILD_SUBREAPER, 1, 0, 0, 0) == 0
    try:
        svc = service()
        io = svc.io_pid()
        kids = Path(f"/proc/{svc.p.pid}/task/{svc.p.pid}/children").read_text().split()
        svc.p.kill()
        svc.p.wait(10)
        _, status = os.waitpid(io, 0)
        assert os.waitstatus_to_exitcode(status) == 1
        for k in kids:                         # the resource tracker ends once the I/O process has
            if int(k) != io:
                os.waitpid(int(k), 0)
    finally:
        libc.prctl(PR_SET_CHILD_SUBREAPER, 0, 0, 0, 0)
    assert f"the cycle process (pid {svc.p.pid}) died: the I/O process stops with exit code 1" in svc.text()


def test_sighup_reloads_the_config_and_keeps_the_service_running(service):
    svc = service()
    assert svc.read()["reload_count"] == 0
    svc.p.send_signal(signal.SIGHUP)
    until(lambda: "reload 1 of " in svc.text(), 10.0, "the reload is logged")
    assert "reload 1 of " in svc.text() and "accepted: no change" in svc.text()
    assert svc.read()["reload_count"] == 1
    before = svc.read()["cycle_count"]
    until(lambda: (v := svc.read()) is not None and v["cycle_count"] > before, 10.0, "the cycle goes on")
    assert svc.p.poll() is None
    assert svc.stop() == 0
    assert json.loads(svc.stats.read_text())["status"] == "stopped"


def test_ctrl_c_to_the_process_group_stops_cleanly_without_a_traceback(service):
    svc = service(new_session=True)
    os.killpg(svc.p.pid, signal.SIGINT)            # what Ctrl-C on `make run` does: the whole group
    assert svc.wait() == 0
    log = svc.text()
    assert "Traceback" not in log and "KeyboardInterrupt" not in log, log
    assert "status: stopped" in log
