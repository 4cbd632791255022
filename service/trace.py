"""The trace of a cut, written outside the cycle (`stiffcomp run --trace FILE`, docs/part_format.md).

    cycle process                               trace writer (a process of its own)
    ┌────────────────────────────┐   shared     ┌──────────────────────────────────────────┐
    │ each cycle: one row, one   │   memory     │ every DRAIN_S: the rows since the last,   │
    │ struct copy, count += 1  ──┼─▶ TraceRing ◀┼─ written by stiffness.data.trace_file.TraceFile     │
    └────────────────────────────┘              │ (CSV or Parquet, rotated at a size limit) │
                                                └──────────────────────────────────────────┘

The cycle never waits and never touches a file: `TraceRing.put_cycle` packs the row into slot
``count % rows`` and then raises the count (x86-64 keeps the two stores in order, as the process image
relies on). The cycle packs only what it alone knows, 29 values in one struct call: its time (float64), the
joints, wrench, correction, the arm's acceleration and the box's reading (float32, the precision the PLC's
registers carry: 0.3 um at 2 m for a joint), the three words and the box's count (uint16); the cycle count is
the ring's own count, and the wall-clock time its start stamp plus the cycle's time. The ring is small (1.5 MB) and touched once at start-up, so the cycle never
takes a page fault on it. The writer reads the slots between its own count and the cycle's, then checks the count
again: a slot the cycle overwrote meanwhile (the writer fell more than a ring behind, 16 s at 1 ms) is
not written but counted as lost, and the log and the service's statistics say how many. Nothing is
dropped in silence. The writer watches its parent as the I/O process does, and drains the ring to the
last row when the service stops.
"""

from __future__ import annotations

import logging
import multiprocessing
import os
import struct
import time
import weakref
from dataclasses import dataclass
from multiprocessing.shared_memory import SharedMemory
from pathlib import Path

import numpy as np

from io_base.log_format import configure_logging, current_format
from io_process.process import describe_exit, ignore_cycle_signals, spawn_child
from plc_link.image import release
from stiffness.data.trace_file import DEFAULT_KEEP, DEFAULT_MAX_MB, TraceFile, check_path
from stiffness.errors import StiffnessError

from .errors import TraceError

log = logging.getLogger("stiffcomp.trace")

ROWS = 1 << 14          # the ring: 16 s of cycles at 1 ms (the writer drains it every DRAIN_S), 1.8 MB
DRAIN_S = 0.1           # the writer's period
_HEADER = 8             # int64: rows put by the cycle, taken by the writer, lost, written, the start stamp (ns)
_ROW = struct.Struct("<d24f4H")     # 112 bytes: time_s; joints, wrench, correction, acceleration, box; words, count
ROW_DTYPE = np.dtype([("time", "<f8"), ("values", "<f4", (24,)), ("words", "<u2", (4,))])
_START = 4              # the header's start stamp: wall-clock ns at the cycle's time 0
# what each field of a row holds, in `_ROW`'s order (the names of the compiled service's values, `service.app`):
# the compiled cycle packs its row by this table, `put_cycle` in the same order
ROW_SOURCES = ("t", *(f"q{i}" for i in range(1, 7)), *(f"signals.wrench_base[{k}]" for k in range(6)),
               *(f"signals.correction[{k}]" for k in range(6)), "signals.acc_x", "signals.acc_y", "signals.acc_z",
               "signals.box_x", "signals.box_y", "signals.box_z",
               "signals.status_word", "signals.fault_word", "task.task_state", "signals.box_samples")


@dataclass(frozen=True)
class TraceOptions:
    """Where and how much to trace: the file (.csv or .parquet), its size limit and rotated files kept."""

    path: Path
    max_bytes: float = DEFAULT_MAX_MB * 1e6
    keep: int = DEFAULT_KEEP

    def check(self) -> None:
        """TraceError naming the option when the trace cannot be written (before anything starts)."""
        try:
            check_path(self.path)
        except StiffnessError as e:
            raise TraceError(str(e)) from None
        if not self.max_bytes > 0 or self.keep < 0:
            raise TraceError(f"--trace-max-mb must be > 0 and --trace-keep >= 0 (got {self.max_bytes / 1e6:g} MB, "
                             f"{self.keep})")


class TraceRing:
    """Trace rows in shared memory: one writer (the cycle), one reader (the trace writer); pickles to a handle."""

    def __init__(self, rows: int = ROWS, _name: str | None = None):
        self.rows = int(rows)
        self._owner = _name is None
        self.shm = SharedMemory(name=_name, create=self._owner, size=8 * _HEADER + _ROW.size * self.rows)
        self.header = np.ndarray((_HEADER,), dtype=np.int64, buffer=self.shm.buf)
        self.table = np.ndarray((self.rows,), dtype=ROW_DTYPE, buffer=self.shm.buf, offset=8 * _HEADER)
        if self._owner:
            self.header[:] = 0
            self.table.view(np.uint8)[:] = 0     # every page faulted in now, at start-up, not by the cycle's first pass
        self._pack, self._buf = _ROW.pack_into, self.shm.buf
        self._bytes = np.ndarray((self.shm.size,), dtype=np.uint8, buffer=self.shm.buf)
        self._put_count = self.shm.buf[:8].cast("q")     # the cycle's own store of its count (cheaper than NumPy's)
        self._n = int(self.header[0])
        self._release = weakref.finalize(self, release, self.shm, self._owner, (self._put_count,))

    def __reduce__(self):
        return (TraceRing, (self.rows, self.shm.name))

    def put_cycle(self, t: float, q_deg, sig, task_state: int) -> None:
        """The cycle's side: its row from its time, the joints the PLC reported and its `Signals`
        (`service.pipeline`); never waits. The first row stamps the wall-clock time of the cycle's time 0."""
        n = self._n
        if not n:
            self.header[_START] = time.time_ns() - int(t * 1e9)
        self._pack(self._buf, 8 * _HEADER + _ROW.size * (n % self.rows), t, *q_deg, *sig.wrench_base,
                   *sig.correction, sig.acc_x, sig.acc_y, sig.acc_z, sig.box_x, sig.box_y, sig.box_z, sig.status_word,
                   sig.fault_word, task_state, sig.box_samples)
        self._n = n = n + 1
        self._put_count[0] = n

    def put_with(self, write, t: float) -> None:
        """`put_cycle` for the compiled cycle: ``write(memory, offset)`` packs the row (by `ROW_SOURCES`) into
        the ring's bytes (a uint8 array) at ``offset``; ``t``: the cycle's time (s)."""
        n = self._n
        if not n:
            self.header[_START] = time.time_ns() - int(t * 1e9)
        if not write(self._bytes, 8 * _HEADER + _ROW.size * (n % self.rows)):
            raise OverflowError("a value of the trace's row is beyond float32's range")
        self._n = n = n + 1
        self._put_count[0] = n

    def take(self) -> np.ndarray:
        """The writer's side: a copy of the rows put since the last take (lost rows counted, not returned)."""
        h = self.header
        start, end = int(h[1]), int(h[0])
        if end - start > self.rows:                 # already overwritten before we came
            h[2] += end - start - self.rows
            start = end - self.rows
        idx = np.arange(start, end) % self.rows
        rows = self.table[idx]
        t = rows["time"][:, None]
        cycle = np.arange(start + 1, end + 1, dtype=np.float64)[:, None]          # cycle k is the k-th row put
        out = np.concatenate([t, t + int(self.header[_START]) * 1e-9, cycle, rows["values"].astype(np.float64),
                              rows["words"].astype(np.float64)], axis=1)
        now = int(h[0])
        clobbered = max(0, now - self.rows - start)      # slots the cycle wrote again while we copied
        if clobbered:
            h[2] += min(clobbered, len(out))
            out = out[min(clobbered, len(out)):]
        h[1] = end
        return out

    @property
    def counts(self) -> dict[str, int]:
        return {"cycles": int(self.header[0]), "written": int(self.header[3]), "lost": int(self.header[2])}

    def close(self) -> None:
        """Detach (the creator also frees the memory), as `ProcessImage.close`; so also when collected without."""
        self.header = self.table = None
        self._buf = self._bytes = self._put_count = None
        self._release()


def _writer_main(ring: TraceRing, options: TraceOptions, log_level: int, log_format: str, stop, ready) -> None:
    ignore_cycle_signals()
    configure_logging(log_level, log_format)
    parent = os.getppid()
    try:
        out = TraceFile(options.path, options.max_bytes, options.keep)
    except StiffnessError as e:
        ready.send(str(e))
        ring.close()
        return
    ready.send("")
    lost = 0
    try:
        while True:
            done = stop.wait(DRAIN_S) or os.getppid() != parent
            rows = ring.take()
            out.write(rows)
            ring.header[3] += len(rows)
            if int(ring.header[2]) > lost:
                log.warning("trace: %d cycle(s) lost so far: the writer fell more than %d cycles behind (a slow "
                            "disk?)", int(ring.header[2]), ring.rows)
                lost = int(ring.header[2])
            if done:
                break
    finally:
        out.close()
        ring.close()


class TraceWriter:
    """The trace writer process: drains ``ring`` into ``options.path`` until `stop`.

    Parameters
    ----------
    ring : TraceRing
        Created by the service; the cycle `put`s into it.
    options : TraceOptions
    """

    def __init__(self, ring: TraceRing, options: TraceOptions):
        ctx = multiprocessing.get_context("spawn")
        self.ring, self.options = ring, options
        self._stop = ctx.Event()
        self._ready, child_end = ctx.Pipe(duplex=False)
        self._proc = ctx.Process(target=_writer_main, name="stiffcomp-trace", daemon=True, args=(
            ring, options, logging.getLogger().getEffectiveLevel(), current_format(), self._stop, child_end))
        self._child_end = child_end

    def start(self, timeout: float = 60.0) -> None:
        """Start it; StiffnessError when it cannot write the file (nothing else started yet)."""
        spawn_child(self._proc)
        self._child_end.close()
        msg = self._ready.recv() if self._ready.poll(timeout) else "the trace writer did not start in time"
        if msg:
            self.stop()
            raise TraceError(msg)
        log.info("tracing every cycle to %s (rotated at %.0f MB, %d kept)", self.options.path,
                 self.options.max_bytes / 1e6, self.options.keep)

    def stop(self, timeout: float = 60.0) -> dict[str, int]:
        """Stop after it wrote every row the cycle put; returns the ring's counts."""
        self._stop.set()
        if self._proc.pid is not None:
            self._proc.join(timeout)
            if self._proc.is_alive():
                log.error("the trace writer did not finish in %g s; stopped", timeout)
                self._proc.kill()
                self._proc.join(2.0)
            elif self._proc.exitcode:
                log.error("the trace writer ended with %s", describe_exit(self._proc.exitcode))
        self._ready.close()
        counts = self.ring.counts
        missing = counts["cycles"] - counts["written"]
        (log.warning if missing else log.info)(
            "trace: %d of %d cycles written to %s%s", counts["written"], counts["cycles"], self.options.path,
            f" ({missing} lost, see above)" if missing else "")
        return counts

    @property
    def alive(self) -> bool:
        return self._proc.is_alive()
