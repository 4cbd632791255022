"""Real-time scheduling: SCHED_FIFO for the calling thread, and the CPUs' idle wake-up latency for the whole
host; each where permitted, with one warning where not."""

from __future__ import annotations

import logging
import os
import struct


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


CPU_LATENCY_DEVICE = "/dev/cpu_dma_latency"


def hold_cpu_latency(us: int, device: str = CPU_LATENCY_DEVICE) -> tuple[int | None, str | None]:
    """Ask the kernel to keep every CPU's idle state within ``us`` microseconds of waking, for as long as the
    returned file descriptor stays open (close it to let go): (fd, None), or (None, why it was not permitted).

    The kernel's CPU latency QoS (Documentation/power/pm_qos_interface.rst): a process that holds
    ``/dev/cpu_dma_latency`` open, having written its target as an s32, has a request the idle governor
    obeys; 0 keeps idle CPUs polling instead of halting, so a datagram or a deadline is served at once rather
    than after the idle state's exit latency, on a virtual machine the host's rescheduling of a halted vCPU
    (milliseconds). Real-time hosts do the same (cyclictest holds it at 0). The device is root's unless a
    udev rule grants it."""
    try:
        fd = os.open(device, os.O_WRONLY | os.O_CLOEXEC)
    except OSError as e:
        return None, f"{device}: {e.strerror}"
    try:
        os.write(fd, struct.pack("=i", us))
    except OSError as e:
        os.close(fd)
        return None, f"{device}: {e.strerror}"
    return fd, None
