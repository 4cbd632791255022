"""The cyclic task: absolute deadlines, the exceed counter, stats, and the error policy."""

from __future__ import annotations

import os
import struct
import threading
import time

import pytest

from service.task import CyclicTask, TaskInfo


def run_task(work, n_cycles, period=1e-3):
    info = TaskInfo(period, history=1000)
    done, errors = threading.Event(), []

    def wrapped(t, exceeded):
        work(t, exceeded, info)
        if info.cycle_count + 1 >= n_cycles:
            done.set()

    task = CyclicTask(period, wrapped, info, errors.append)
    task.start()
    done.wait(10.0)
    task.stop()
    assert not task.running
    return info, errors


def test_deadlines_are_absolute_so_start_times_do_not_drift():
    times = []
    _, errors = run_task(lambda t, ex, info: times.append(t), 200)
    assert errors == []
    # the k-th cycle starts at or after its deadline k * period (never before)
    assert all(t >= k * 1e-3 - 1e-9 for k, t in enumerate(times))
    assert times == sorted(times)


def test_overrunning_work_is_counted_and_flagged_to_the_next_cycle():
    flags = []

    def work(t, exceeded, info):
        flags.append(exceeded)
        if info.cycle_count == 5:
            time.sleep(0.0035)          # this cycle's work runs past the next deadlines

    info, _ = run_task(work, 20)
    assert info.exceed_count >= 1
    assert flags[6] is True
    assert info.max_exec_s >= 0.0035


def test_stats_document_has_the_documented_keys():
    info, _ = run_task(lambda t, ex, info: None, 50)
    s = info.stats()
    assert set(s) == {"cycles", "exceed_count", "exec_us", "period_jitter_us"}
    assert set(s["exec_us"]) == {"p50", "p99", "max"}
    assert set(s["period_jitter_us"]) == {"p99", "p999", "max"}
    assert s["cycles"] >= 50
    assert 0 <= s["exec_us"]["p50"] <= s["exec_us"]["p99"] <= s["exec_us"]["max"]


def test_an_error_in_the_work_goes_to_the_policy_and_stops_the_task():
    def work(t, exceeded, info):
        if info.cycle_count == 3:
            raise ZeroDivisionError("boom")

    info = TaskInfo(1e-3, history=1000)
    seen = []
    task = CyclicTask(1e-3, lambda t, ex: work(t, ex, info), info, seen.append)
    task.start()
    for _ in range(500):
        if seen:
            break
        time.sleep(0.005)
    task.stop()
    assert len(seen) == 1 and isinstance(seen[0], ZeroDivisionError)
    assert not task.running


def test_history_is_a_ring_buffer():
    info = TaskInfo(1e-3, history=1000)
    for k in range(2500):
        info.record(1e-5 * (k % 7), 1e-6)
    assert info.stats()["cycles"] == 2500
    assert info.stats()["exec_us"]["max"] == pytest.approx(60.0)


def test_the_collector_is_off_in_the_cycle_and_collects_young_garbage_only_between_cycles():
    """gc is disabled while the task runs (no collection at an allocation in the work), cyclic garbage the
    work leaves is still collected (after a cycle's work, with slack left), and gc is on again after."""
    import gc

    from service.task import GC_YOUNG_MAX

    seen: list[tuple[bool, int]] = []
    done = threading.Event()

    def work(t, exceeded):
        for _ in range(2000):                   # cyclic garbage: only the collector frees it
            a: list = []
            a.append(a)
        seen.append((gc.isenabled(), gc.get_count()[0]))
        if len(seen) >= 200:
            done.set()

    was = gc.isenabled()
    task = CyclicTask(0.002, work, TaskInfo(0.002, 1000), on_error=lambda e: None)
    task.start()
    try:
        assert done.wait(30)
    finally:
        task.stop()
    assert not any(enabled for enabled, _ in seen)
    # without collections the young generation would hold 200 x 2000 lists by now
    assert max(count for _, count in seen) < min(GC_YOUNG_MAX + 5000, 200 * 2000)
    assert gc.isenabled() == was


def test_memory_not_lockable_is_one_warning_and_the_task_runs(monkeypatch, caplog):
    """Where mlockall is not permitted (no CAP_IPC_LOCK, a low RLIMIT_MEMLOCK) the task says so once and runs."""
    import logging

    import service.task

    monkeypatch.setattr(service.task, "lock_memory", lambda: "Operation not permitted")
    ran = threading.Event()
    task = CyclicTask(1e-3, lambda t, e: ran.set(), TaskInfo(1e-3, 1000), on_error=lambda e: None,
                      lock_memory=True)
    with caplog.at_level(logging.WARNING, "stiffcomp.task"):
        task.start()
        assert ran.wait(10)
        task.stop()
    lines = [r.getMessage() for r in caplog.records if "mlockall" in r.getMessage()]
    assert len(lines) == 1 and "Operation not permitted" in lines[0]


def test_a_task_locks_its_memory_where_permitted_and_unlocks_it_after():
    """VmLck (/proc/self/status) is above zero while the task runs, where this process may lock memory."""
    import service.task

    def locked_kb() -> int:
        with open("/proc/self/status") as f:
            return next((int(line.split()[1]) for line in f if line.startswith("VmLck:")), 0)

    if service.task.lock_memory() is not None:
        pytest.skip("mlockall is not permitted here")
    service.task.unlock_memory()
    seen: list[int] = []
    ran = threading.Event()

    def work(t, exceeded):
        seen.append(locked_kb())
        ran.set()

    task = CyclicTask(1e-3, work, TaskInfo(1e-3, 1000), on_error=lambda e: None, lock_memory=True)
    task.start()
    assert ran.wait(10)
    task.stop()
    assert seen[0] > 0 and locked_kb() == 0


def cpu_latency_target() -> int:
    """The kernel's CPU latency QoS target now (µs): reading the device gives it (pm_qos_interface.rst)."""
    fd = os.open("/dev/cpu_dma_latency", os.O_RDONLY)
    try:
        return struct.unpack("=i", os.read(fd, 4))[0]
    finally:
        os.close(fd)


def test_a_task_holds_the_cpus_idle_wakeup_while_it_runs_and_lets_go_after():
    """cpu_latency_us = 0: while the task runs the kernel's target is 0 (idle CPUs poll); after it, what it was."""
    from io_base.scheduling import hold_cpu_latency

    fd, why = hold_cpu_latency(0)
    if why is not None:
        pytest.skip(f"the CPU latency QoS is not permitted here ({why})")
    os.close(fd)
    before = cpu_latency_target()
    if before == 0:
        pytest.skip("another process holds the target at 0 already")
    seen: list[int] = []
    ran = threading.Event()

    def work(t, exceeded):
        if not seen:
            seen.append(cpu_latency_target())
            ran.set()

    task = CyclicTask(1e-3, work, TaskInfo(1e-3, 1000), on_error=lambda e: None, cpu_latency_us=0)
    task.start()
    try:
        assert ran.wait(10)
    finally:
        task.stop()
    assert seen == [0] and cpu_latency_target() == before


def test_an_idle_wakeup_not_permitted_is_one_warning_naming_the_device_and_the_task_runs(monkeypatch, caplog):
    """Where the device may not be opened (not root, no udev rule; here a device that is not there) the task
    says so once, naming it, and runs."""
    import logging

    import service.task
    from io_base.scheduling import hold_cpu_latency

    monkeypatch.setattr(service.task, "hold_cpu_latency", lambda us: hold_cpu_latency(us, "/dev/no_such_qos"))
    ran = threading.Event()
    task = CyclicTask(1e-3, lambda t, e: ran.set(), TaskInfo(1e-3, 1000), on_error=lambda e: None,
                      cpu_latency_us=0)
    with caplog.at_level(logging.WARNING, "stiffcomp.task"):
        task.start()
        assert ran.wait(10)
        task.stop()
    lines = [r.getMessage() for r in caplog.records if "idle wake-up" in r.getMessage()]
    assert len(lines) == 1 and "/dev/no_such_qos" in lines[0], lines
