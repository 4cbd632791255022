"""Fixtures of the service tests: a leak check around every test, temporary configs."""

from __future__ import annotations

import multiprocessing
import threading
import time

import pytest

from service.testing import leaked_threads, sockets_open


@pytest.fixture(autouse=True)
def no_leaks():
    """Every test leaves no thread, socket or child process behind."""
    threads = set(threading.enumerate())
    socks = sockets_open()
    yield
    assert leaked_threads(threads) == []
    deadline = time.monotonic() + 2.0
    while sockets_open() - socks and time.monotonic() < deadline:
        time.sleep(0.02)
    assert sockets_open() - socks == set()
    assert multiprocessing.active_children() == []
