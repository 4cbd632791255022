"""Real-time scheduling of the calling thread: SCHED_FIFO where permitted, one warning where not."""

from __future__ import annotations

import logging
import os


def set_fifo(priority: int, what: str, log: logging.Logger) -> bool:
    """Run the calling thread under SCHED_FIFO at ``priority`` (0: leave the scheduler alone); True when set.
    Without CAP_SYS_NICE it logs one warning naming ``what`` and runs on at normal priority."""
    if priority <= 0:
        return False
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
    except (OSError, AttributeError) as e:
        log.warning("cannot set SCHED_FIFO priority %d for the %s (%s); running with normal priority", priority,
                    what, e)
        return False
    log.info("%s runs with SCHED_FIFO priority %d", what, priority)
    return True
