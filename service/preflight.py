"""What `stiffcomp run --check` checks beyond the config and the files it names: what `stiffcomp run` needs of
this machine before its first cycle, asked of the operating system now, with nothing started.

* every address the I/O process would listen on, as its own settings declare them (``plc.port``,
  ``plc.tls.port``, ``robot.port``, ``ads.port``, ``monitoring.port``: `io_process.server.IoSettings.listeners`,
  the list `IoServer.start` starts from): an address of this machine, the port free, no two keys on one port.
  A refusal here is what `run` refuses at its start (`StartCheckError`, exit code 2). A port in use by a
  stiffcomp service that answers on ``monitoring.port`` (an edited file checked beside the running service,
  docs/commissioning.md) is a note: it is free once that service stops;
* what the service asks of the scheduler (``cycle.realtime_priority``, ``robot.realtime_priority``,
  ``cycle.lock_memory``, ``cycle.cpu``, ``cycle.cpu_latency_us``): `run` warns and runs on without it, so
  these are notes, not refusals;
* what it cannot check without starting: the PLC a client connects to, the sensor's first frame.

The answers hold for the moment of the check, as the operating system gives them to this process: a port
taken after it, or a `run` started as another user or in another container, can still fail (one line then,
naming the key).
"""

from __future__ import annotations

import errno
import http.client
import os
import threading
from dataclasses import dataclass, field

from io_base.listen import Listener, bind_error, bind_problem
from io_base.scheduling import hold_cpu_latency
from io_process.endpoints import read_health

from .errors import ServiceConfigError
from .io_config import io_listeners


class StartCheckError(ServiceConfigError):
    """`stiffcomp run --check` found something `stiffcomp run` would refuse before its first cycle."""


@dataclass
class Findings:
    """What the check found: ``checked`` (what passed), ``notes`` (what run would warn about, and what the
    check could not see)."""

    checked: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)


def check_start(cfg) -> Findings:
    """Check what `stiffcomp run` needs of this machine for ``cfg`` (a validated `ServiceConfig`); raises
    StartCheckError naming the file, every key that fails and why (one line each)."""
    found = Findings()
    listeners = io_listeners(cfg)
    problems = _shared_ports(listeners)
    running = None                      # the stiffcomp service holding this config's ports, where one answers
    for key, host, port, transport in listeners:
        e = bind_error(host, port, transport)
        if e is None:
            found.checked.append(f"{key} {host}:{port}/{transport} free")
            continue
        if e.errno == errno.EADDRINUSE:
            running = running or _running_service(cfg)
            if running:
                found.notes.append(f"{key} {host}:{port}/{transport} is in use, {running}: checking an edited "
                                   "file beside the running service, the port is free once it stops")
                continue
        problems.append(f"{key} = {port} on {host} ({transport}): {bind_problem(host, port, key, transport)}")
    if problems:
        raise StartCheckError(f"{cfg.path}: run would not start: " + "; ".join(problems))
    found.notes += _scheduling(cfg)
    found.notes += _unseen(cfg)
    return found


def _running_service(cfg) -> str | None:
    """"by the stiffcomp service answering at <monitoring address>" when one answers its liveness probe there
    (the service this config runs, as when an edited file is checked beside it), else None."""
    m = cfg.monitoring
    if not m.enabled:
        return None
    host = {"0.0.0.0": "127.0.0.1", "::": "::1", "": "127.0.0.1"}.get(m.host, m.host)
    try:
        read_health(host, m.port, "live", timeout_s=0.5)
    except (OSError, http.client.HTTPException, ValueError):
        return None
    return f"by the stiffcomp service answering at {host}:{m.port}"


def _shared_ports(listeners: list[Listener]) -> list[str]:
    """Two keys of the config on one port of one transport: the second server cannot bind it."""
    seen: dict[tuple[int, str], str] = {}
    out = []
    for key, _, port, transport in listeners:
        if (port, transport) in seen:
            out.append(f"{key} = {port} is {seen[port, transport]} too: give each server its own port")
        seen.setdefault((port, transport), key)
    return out


def _scheduling(cfg) -> list[str]:
    """What run would warn about the scheduling it asks for (it runs on without it)."""
    from .task import lock_memory, unlock_memory

    notes = []
    c = cfg.cycle
    for key, prio in (("cycle.realtime_priority", c.realtime_priority),
                      ("robot.realtime_priority", cfg.robot.realtime_priority if cfg.robot.enabled else 0)):
        why = fifo_problem(prio)
        if why is not None:
            notes.append(f"{key} = {prio}: SCHED_FIFO is not permitted here ({why}); run would warn and run at "
                         "normal priority (CAP_SYS_NICE or RLIMIT_RTPRIO permits it; docs/service.md)")
    if c.lock_memory:
        why = lock_memory()
        unlock_memory()
        if why is not None:
            notes.append(f"cycle.lock_memory: mlockall is not permitted here ({why}); run would warn and run with "
                         "its memory unlocked (CAP_IPC_LOCK or a higher RLIMIT_MEMLOCK permits it)")
    if c.cpu_latency_us is not None:
        fd, why = hold_cpu_latency(c.cpu_latency_us)
        if fd is not None:
            os.close(fd)
        else:
            notes.append(f"cycle.cpu_latency_us = {c.cpu_latency_us}: the CPUs' idle wake-up cannot be held ({why}); "
                         "run would warn and leave it to the kernel (root, or write access by a udev rule)")
    if c.cpu is not None and c.cpu not in os.sched_getaffinity(0):
        notes.append(f"cycle.cpu = {c.cpu} is not among the CPUs this process may use "
                     f"({sorted(os.sched_getaffinity(0))}); run would warn and leave the cycle thread unpinned")
    return notes


def fifo_problem(priority: int) -> str | None:
    """Why a thread of this process may not run under SCHED_FIFO at ``priority`` (None: it may, or 0 asks
    nothing). Asked on a thread of its own that ends at once, so this process keeps its scheduling."""
    if priority <= 0:
        return None
    answer: list[str | None] = []

    def ask() -> None:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
            answer.append(None)
        except (OSError, AttributeError) as e:
            answer.append(getattr(e, "strerror", None) or str(e))

    t = threading.Thread(target=ask, name="stiffcomp-check-fifo")
    t.start()
    t.join()
    return answer[0] if answer else "the check did not answer"


def _unseen(cfg) -> list[str]:
    """What the check cannot see without starting."""
    notes = []
    if cfg.plc.role == "client":
        notes.append(f"plc.role client: the PLC at {cfg.plc.host}:{cfg.plc.port} is reached after the start, "
                     "not checked here")
    if cfg.source.type == "can":
        notes.append("source can: the bus opened, but no frame is awaited; the sensor's first frame is the "
                     "start's (faults.sensor_timeout_ms)")
    if cfg.robot.enabled:
        notes.append("robot: the robot's packets arrive after the start, not checked here")
    return notes
