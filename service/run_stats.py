"""What a service run reports of itself: the log line of its statistics (`stiffcomp run --stats-interval`, and
at its end) and the ``--stats-json`` file."""

from __future__ import annotations

import json
import logging
from pathlib import Path

import numpy as np

from plc_link.contract import TaskState

log = logging.getLogger("stiffcomp.service")


def log_stats(service) -> None:
    """One log line: the task's counts and timing, the faults active, the correction."""
    stats = service.info.stats()
    cycle = service.cycle
    log.info("task: cycles %d, exceed %d, exec p50/p99/max %.1f/%.1f/%.1f us, jitter p99.9 %.1f us; "
             "faults [%s]; correction %s deg", stats["cycles"], stats["exceed_count"], stats["exec_us"]["p50"],
             stats["exec_us"]["p99"], stats["exec_us"]["max"], stats["period_jitter_us"]["p999"],
             ", ".join(cycle.faults.active()) or "none", np.array2string(np.array(cycle.correction), precision=4))


def write_stats(service, path: str | Path) -> dict:
    """The task's statistics, the status, why the service failed, the I/O process's deaths and restarts, the
    robot road's and the trace's counts, the modes the follower took (`dynamics_stats`), as JSON to ``path``;
    returned."""
    stats = service.info.stats()
    stats["status"] = "stopped" if service.task_state == TaskState.STOP else "running"
    stats["failure"] = service.failure
    io = service.io_watch
    stats["io_process"] = {"deaths": io.deaths, "restarts": io.restarts}
    if service.cfg.robot.enabled:
        stats["robot"] = io.road_stats
    if service.trace_counts is not None:
        stats["trace"] = {"file": str(service.trace_options.path), **service.trace_counts}
    stats.update(dynamics_stats(service))
    Path(path).write_text(json.dumps(stats, indent=2) + "\n")
    return stats


def dynamics_stats(service) -> dict:
    """With ``dynamics.observer.follow``, {"dynamics": {"followed": [...]}}: each mode's configured frequency,
    the one in use and how often the follower changed it (`stiffness.dynamics.follower`); else {}."""
    dynamics = service.cycle.compensator.dynamics
    follower = None if dynamics is None else dynamics.follower
    if follower is None:
        return {}
    return {"dynamics": {"followed": [{"configured_hz": m.configured_hz, "hz": m.hz, "changes": m.changes}
                                      for m in follower.modes]}}
