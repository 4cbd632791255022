"""`stiffcomp run --check` checks what `run` needs of this machine before its first cycle (issue 45, item 3): a
host that is not this machine's, a port in use, two keys on one port each exit 2 naming the key and why; a
port held by the running service itself (an edited file checked beside it) is a note; and a start that fails
says so, with no line that reads like a start and a clean stop."""

from __future__ import annotations

import os
import socket
import subprocess
import sys

import pytest

from hil.testing import ROOT, free_port, write_config
from service.app import Service
from service.config import SHIPPED, load_config
from service.preflight import fifo_problem
from tools.cli import main


def refused(capsys, code: int, *words: str) -> str:
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and len(err.strip().splitlines()) == 1, err
    for w in words:
        assert w in err, err
    return err


def check(cfg) -> int:
    return main(["run", "--check", "--config", str(cfg)])


def test_a_host_that_is_not_this_machines_is_refused(tmp_path, capsys):
    cfg = write_config(tmp_path, {"plc": {"host": "192.0.2.1", "port": free_port()}})      # TEST-NET-1
    refused(capsys, check(cfg), str(cfg), "plc.port", "192.0.2.1 is not an address of this machine")


@pytest.mark.serial           # the shipped config's ports (ADS 48898 and the others) are the whole host's
def test_the_shipped_kuka_config_is_refused_as_run_refuses_it(capsys):
    """The issue's case: robot.host 192.168.1.10 (ADAPT in the file) is no address of this machine."""
    cfg = SHIPPED / "robot_kuka_rsi.yaml"
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        try:
            s.bind(("192.168.1.10", 0))
        except OSError:
            pass                                        # not an address of this machine: the case tested
        else:
            pytest.skip("this machine has the address 192.168.1.10")
    refused(capsys, check(cfg), "robot.port", "(udp)", "192.168.1.10 is not an address of this machine")


def test_a_tcp_port_in_use_is_refused_naming_the_key(tmp_path, capsys):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        cfg = write_config(tmp_path, {"plc": {"port": free_port()}, "ads": {"enabled": True, "port": port}})
        refused(capsys, check(cfg), str(cfg), f"ads.port = {port}", "in use", "ss -ltnp")


def test_a_udp_port_in_use_is_refused_naming_the_key(tmp_path, capsys):
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        cfg = write_config(tmp_path, {"plc": {"port": free_port()}, "robot": {"host": "127.0.0.1", "port": port}},
                           source=SHIPPED / "robot_kuka_rsi.yaml")
        refused(capsys, check(cfg), f"robot.port = {port}", "in use", "ss -lunp")


def test_two_keys_on_one_port_are_refused(tmp_path, capsys):
    port = free_port()
    cfg = write_config(tmp_path, {"plc": {"port": port}, "monitoring": {"port": port}})
    refused(capsys, check(cfg), f"monitoring.port = {port} is plc.port too")


def test_a_free_config_passes_and_says_what_it_checked(tmp_path, capsys):
    cfg = write_config(tmp_path, {"plc": {"port": free_port()}})
    assert check(cfg) == 0
    out = capsys.readouterr().out
    data = load_config(cfg)
    assert "ok, the service would start" in out
    for key, port in (("plc.port", data.plc.port), ("monitoring.port", data.monitoring.port)):
        assert f"{key} 127.0.0.1:{port}/tcp free" in out


def test_what_run_would_only_warn_about_and_what_it_cannot_see_are_notes(tmp_path, capsys):
    """A CPU this process may not use (run leaves the cycle unpinned) and a robot whose packets come after the
    start: the check passes, saying each as a note. The process is held to its first CPU for the check."""
    allowed = os.sched_getaffinity(0)
    if len(allowed) < 2:
        pytest.skip("needs two CPUs this process may use, to keep it off one")
    first, cpu = sorted(allowed)[:2]
    cfg = write_config(tmp_path, {"plc": {"port": free_port()}, "cycle": {"cpu": cpu},
                                  "robot": {"interface": "kuka_rsi", "host": "127.0.0.1", "port": free_port(),
                                            "kuka_rsi": {}}})
    os.sched_setaffinity(0, {first})
    try:
        code = check(cfg)
    finally:
        os.sched_setaffinity(0, allowed)
    out = capsys.readouterr().out
    assert code == 0, out
    assert "ok, the service would start" in out
    notes = [line for line in out.splitlines() if "note" in line]
    assert any(f"cycle.cpu = {cpu} is not among the CPUs" in n and "unpinned" in n for n in notes), out
    assert any("robot's packets arrive after the start, not checked here" in n for n in notes), out


def test_the_priority_check_leaves_this_process_as_it_was():
    before = os.sched_getscheduler(0), os.sched_getparam(0).sched_priority
    fifo_problem(10)
    assert (os.sched_getscheduler(0), os.sched_getparam(0).sched_priority) == before
    assert fifo_problem(0) is None


@pytest.mark.realtime
def test_ports_held_by_the_running_service_are_a_note_not_a_refusal(tmp_path, capsys):
    """Checking the running service's own config beside it (docs/commissioning.md): its ports are in use, by it."""
    cfg = write_config(tmp_path, {"plc": {"port": free_port()}})
    service = Service(load_config(cfg))
    try:
        service.start()
        capsys.readouterr()
        assert check(cfg) == 0
        out = capsys.readouterr().out
    finally:
        service.stop()
    assert "plc.port" in out and "is in use, by the stiffcomp service answering at" in out


@pytest.mark.realtime
def test_a_start_that_fails_says_so_and_nothing_reads_like_a_start(tmp_path):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        cfg = write_config(tmp_path, {"plc": {"port": taken.getsockname()[1]}})
        p = subprocess.run([sys.executable, "-m", "tools.cli", "run", "--config", str(cfg)], check=False, cwd=ROOT,
                           capture_output=True, text=True, timeout=120)
    assert p.returncode == 2, p.stderr
    assert "did not start" in p.stderr and "in use" in p.stderr.splitlines()[-1]
    for looks_like_a_run in ("ready", "stopped after", "service running", "task: cycles"):
        assert looks_like_a_run not in p.stderr, p.stderr
