"""Fixtures every test suite may use. ``no_leaks`` checks that a test leaves no thread, socket,
child process or zombie behind; the suites that start devices request it for every test."""

from __future__ import annotations

import multiprocessing
import os
import threading
import time
from multiprocessing import resource_tracker

import pytest

from hil.testing import leaked_threads, sockets_open


def child_pids() -> set[int]:
    """Processes whose parent is this one (Linux /proc): multiprocessing children and subprocesses alike."""
    me, out = os.getpid(), set()
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    if int(f.read().rsplit(")", 1)[1].split()[1]) == me:
                        out.add(int(d))
            except (OSError, IndexError, ValueError):
                continue
    return out


@pytest.fixture
def no_leaks():
    """Every test leaves no thread, socket, child process or zombie behind."""
    resource_tracker.ensure_running()     # multiprocessing's own helper lives as long as this interpreter
    threads = set(threading.enumerate())
    socks = sockets_open()
    children = child_pids()
    yield
    assert leaked_threads(threads) == []
    deadline = time.monotonic() + 2.0
    while sockets_open() - socks and time.monotonic() < deadline:
        time.sleep(0.02)
    assert sockets_open() - socks == set()
    assert multiprocessing.active_children() == []
    assert child_pids() - children == set()
