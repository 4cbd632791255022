"""`stiffcomp reload` finds the service only through a live run file: none, or one left by a service that
is gone (its lock free), is "no service runs with FILE" (exit 2), never a SIGHUP to whatever has the pid."""

from __future__ import annotations

import json
import os

from tools.cli import main
from tools.run_file import RunFile, read_run_file, run_file_for


def test_without_a_running_service_reload_says_so_and_exits_2(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("STIFFCOMP_RUN_DIR", str(tmp_path / "run"))
    cfg = tmp_path / "service.yaml"
    assert main(["reload", "--config", str(cfg)]) == 2
    assert f"no service runs with {cfg}" in capsys.readouterr().err


def test_a_run_file_whose_lock_is_free_is_stale(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("STIFFCOMP_RUN_DIR", str(tmp_path / "run"))
    cfg = tmp_path / "service.yaml"
    held = RunFile(cfg)
    assert held.claim()
    assert not RunFile(cfg).claim()                        # one service per config holds it
    path = run_file_for(cfg)
    path.write_text(json.dumps({"pid": os.getpid(), "config": str(cfg), "reloads": {"attempts": 0}}))
    assert read_run_file(cfg)["pid"] == os.getpid()        # locked: a running service
    held._lock.close()                                     # the service was killed: the lock is free
    held._lock = None
    assert read_run_file(cfg) is None
    assert main(["reload", "--config", str(cfg)]) == 2     # and no SIGHUP went to this process's pid
    assert "no service runs" in capsys.readouterr().err
