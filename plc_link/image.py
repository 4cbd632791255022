"""The process image: where the cycle process and the I/O process meet, in shared memory, without a lock.

TwinCAT's task owns its process image and the ADS router and Modbus server meet it only there; so do
ours. Each direction (``to_plc``, written by the cycle; ``from_plc``, written by the I/O process) has
two buffers of the whole block and a version counter. Each buffer carries its own sequence number,
odd while it is being written (a seqlock per buffer):

    writer:  b = (version + 1) & 1;  seq[b] += 1;  write buffer b;  seq[b] += 1;  version += 1
    reader:  b = version & 1;  s = seq[b];  copy buffer b;  accept if s is even and seq[b] is still s

The writer never waits. A reader reads the newest complete buffer, which the writer touches again only
two versions later, so a copy fails only if two whole publishes happen during it; it then retries. The
cycle retries at most `RETRIES` times and otherwise keeps its last good copy (counted in
``stale_reads``): it never waits on the other process. Each side is single-writer: the cycle thread
for to_plc, the I/O process's one asyncio loop for from_plc.

Memory order: the counters and words are plain stores to shared memory. x86-64 keeps stores in order
and loads in order (total store order), which is what the protocol needs; on a weakly ordered CPU
(ARM) this image would need fences and is not supported.

Modbus rules (I/O side): reads must fall inside a block; writes must fall inside the PLC's registers
(``from_plc``) and cover every register they touch whole (no half of a 32-bit value); anything else
is refused (False) and changes nothing.
"""

from __future__ import annotations

import time
import weakref
from multiprocessing.shared_memory import SharedMemory

import numpy as np

from .contract import REQUIRED, FromPlc, ToPlc, to_plc
from .register_map import RegisterMap

RETRIES = 3
TIMING_RING = 8192      # cycles of (exec, jitter) kept for the I/O side's histograms (8 s at 1 ms)
DIRECTIONS = ("to_plc", "from_plc")
# header (int64): version, seq of buffer 0, seq of buffer 1, stamp (ns) of buffer 0, of buffer 1, per direction
_H = {"to_plc": 0, "from_plc": 5}
_HEADER = 10


# The cycle's side of the protocol as plain functions over the image's memory: the image's methods call them,
# and the compiled service's steady cycle compiles the same functions (`service.kernel.steady_cycle`), so the
# protocol has one implementation whichever runs it. ``h``: the header's int64s; ``k``: a direction's first
# place in it (`_H`); buffers are byte ranges of ``mem`` (memoryviews here, arrays when compiled).
def copy_bytes(dst, src) -> None:
    """``dst[:] = src``, of equal lengths. Compiled (`service.kernel.steady_cycle`), it is a loop: numba's slice
    assignment carries a shape error whose message alone takes some 2.5 s to compile for each model."""
    dst[:] = src


def read_newest(h, k: int, off0: int, off1: int, n: int, mem, scratch, out) -> bool:
    """Copy the ``n`` bytes of direction ``k``'s newest complete buffer into ``out`` (through ``scratch``: a
    failed copy leaves ``out`` as it was); False after `RETRIES` copies overtaken by the writer."""
    for _ in range(RETRIES):
        b = h[k] & 1
        s = h[k + 1 + b]
        if s & 1:
            continue
        o = off0 if b == 0 else off1
        copy_bytes(scratch, mem[o:o + n])
        if h[k + 1 + b] == s:
            copy_bytes(out, scratch)
            return True
    return False


def open_buffer(h, k: int) -> int:
    """Open direction ``k``'s free buffer for writing (its sequence odd); its number."""
    b = (h[k] + 1) & 1
    h[k + 1 + b] += 1
    return b


def close_buffer(h, k: int, b: int, stamp_ns: int, published: bool) -> None:
    """Close buffer ``b`` of direction ``k`` (its sequence even again); when ``published``, stamped and made
    the newest (the version counts up), else as it was before it opened (nothing was written)."""
    if published:
        h[k + 3 + b] = stamp_ns
    h[k + 1 + b] += 1
    if published:
        h[k] += 1


def note_timing(count, ring, exec_us: float, jitter_us: float) -> None:
    """One cycle's (exec, jitter) into the timing ring (``ring``: float32 rows, ``count``: one int64)."""
    n = count[0]
    i = n % TIMING_RING
    ring[i, 0] = exec_us
    ring[i, 1] = jitter_us
    count[0] = n + 1


class ProcessImage:
    """Both blocks of the register map, double-buffered in shared memory; pickles to a handle.

    Parameters
    ----------
    rmap : RegisterMap
    """

    def __init__(self, rmap: RegisterMap, _name: str | None = None):
        self.rmap = rmap
        self.out_codec, self.in_codec = rmap.codecs["to_plc"], rmap.codecs["from_plc"]
        self.tables = {d: (b.table, b.start, b.size) for d, b in rmap.blocks.items()}
        sizes = {d: b.size for d, b in rmap.blocks.items()}
        n_bytes = 8 * _HEADER + sum(2 * 2 * n for n in sizes.values()) + 8 + 8 * TIMING_RING
        self._owner = _name is None
        self.shm = SharedMemory(name=_name, create=self._owner, size=n_bytes)
        # the counters as plain int64 views: a NumPy scalar costs ~0.2 us per access, six each publish
        self._h = self.shm.buf[: 8 * _HEADER].cast("q")
        self._buf, self._off, off = {}, {}, 8 * _HEADER
        for d in DIRECTIONS:
            self._buf[d] = np.ndarray((2, sizes[d]), dtype=np.uint16, buffer=self.shm.buf, offset=off)
            self._off[d] = (off, off + 2 * sizes[d])      # byte offsets of the two buffers
            off += 4 * sizes[d]
        # per-cycle timings: a count, then a ring of (last_exec_us, period_jitter_us) as float32 pairs
        self._n_timing = self.shm.buf[off: off + 8].cast("q")
        self._timing = np.ndarray((TIMING_RING, 2), dtype=np.float32, buffer=self.shm.buf, offset=off + 8)
        self._timing_at, self._mem = off + 8, self.shm.buf
        # the whole image as bytes, for the compiled service's packer (`publish_with`) and its steady call
        self.bytes = np.ndarray((n_bytes,), dtype=np.uint8, buffer=self.shm.buf)
        # `close`, or the image's collection without it: the memoryviews first, then the memory (`release`)
        self._release = weakref.finalize(self, release, self.shm, self._owner, (self._h, self._n_timing))
        if self._owner:
            self._n_timing[0] = 0
            for k in range(_HEADER):
                self._h[k] = 0
            for d in DIRECTIONS:
                self._buf[d][:] = 0
        self.writable = rmap.writable
        self.inner = {a for r in rmap.registers if r.direction == "from_plc"
                      for a in range(r.address + 1, r.address + r.count)}
        self._read_inputs = self.in_codec.record_reader(FromPlc, frozenset(FromPlc._fields) - set(REQUIRED["from_plc"]))
        self._off_in, self._unpack_in = self._off["from_plc"], self.in_codec.unpacker()
        self._off_out = self._off["to_plc"]
        # the cycle's own copy of the PLC's block (`read_newest`, `inputs`), after the scratch it is copied through
        self._in_bytes = n_in = 2 * self.in_codec.words
        self.in_work = np.zeros(2 * n_in, dtype=np.uint8)
        self._in_scratch, self._in_copy = memoryview(self.in_work[:n_in]), memoryview(self.in_work[n_in:])
        assert _H["from_plc"] == 5              # (`inputs` names the counters' places)
        self._last_inputs: FromPlc | None = None
        self.stale_reads = 0            # cycle side: inputs kept from a previous copy
        self.refused_writes = 0         # I/O side: writes refused by the Modbus rules
        self._master: list[int] | None = None   # I/O side: the from_plc block it owns
        self._last_record = to_plc()

    def __reduce__(self):
        return (ProcessImage, (self.rmap, self.shm.name))

    # -- the protocol ---------------------------------------------------------------------------
    def _publish(self, direction: str, words, stamp_ns: int = 0) -> None:
        """Write the block's leading words (the rest never changes) into the free buffer, then publish it."""
        h, k = self._h, _H[direction]
        b = open_buffer(h, k)
        self._buf[direction][b, :len(words)] = words
        close_buffer(h, k, b, stamp_ns, True)

    def _copy(self, direction: str, lo: int, hi: int) -> tuple[int, int, list[int]] | None:
        """(version, stamp, words[lo:hi]) of the newest complete buffer, or None after `RETRIES` failures."""
        h, k, buf = self._h, _H[direction], self._buf[direction]
        for _ in range(RETRIES):
            v = int(h[k])
            b = v & 1
            s = int(h[k + 1 + b])
            if s & 1:
                continue
            words = buf[b, lo:hi].tolist()
            stamp = int(h[k + 3 + b])
            if int(h[k + 1 + b]) == s:
                return v, stamp, words
        return None

    # -- the cycle's side -----------------------------------------------------------------------
    def publish(self, record: ToPlc, stamp_ns: int | None = None) -> None:
        """Publish one cycle's record (each register takes its value by name); never waits. The codec
        packs the values straight into the free buffer (one struct call). ``stamp_ns``: the cycle's
        time (time.time_ns(), the default), for the FILETIME stamps of ADS notifications."""
        h = self._h
        b = open_buffer(h, 0)
        try:
            self.out_codec.pack_into(self._mem, self._off_out[b], self.out_codec.pick(record))
        except BaseException:
            close_buffer(h, 0, b, 0, False)   # the buffer not published: readers go on as before
            raise
        self._last_record = record
        self._published(b, time.time_ns() if stamp_ns is None else stamp_ns, record.last_exec_us,
                        record.period_jitter_us)

    def publish_with(self, write, stamp_ns: int, exec_us: float, jitter_us: float) -> bool:
        """Publish one cycle's block as ``write(memory, offset)`` packs it into the free buffer (the compiled
        cycle's packer, `service.kernel.pack`: ``memory`` the image's bytes as a uint8 array, ``offset`` where
        the block starts) and returns True; never waits. False from ``write`` (nothing written) publishes
        nothing. ``exec_us``, ``jitter_us``: the cycle's timing, for the histograms."""
        h = self._h
        b = open_buffer(h, 0)
        if not write(self.bytes, self._off_out[b]):
            close_buffer(h, 0, b, 0, False)
            return False
        self._published(b, stamp_ns, exec_us, jitter_us)
        return True

    def places(self) -> dict[str, int]:
        """Where a compiled cycle finds the parts of `bytes` it runs this protocol's functions on
        (`service.kernel.steady_cycle`): the header's bytes, the inputs' two buffers and their length (`in_work`
        holds the scratch, then the copy, of that length each), the outputs' two buffers, the timing count."""
        (i0, i1), (o0, o1) = self._off_in, self._off_out
        return {"header_bytes": 8 * _HEADER, "in_off0": i0, "in_off1": i1, "in_bytes": self._in_bytes,
                "out_off0": o0, "out_off1": o1, "timing_count": self._timing_at - 8}

    def _published(self, b: int, stamp_ns: int, exec_us: float, jitter_us: float) -> None:
        """The to_plc buffer ``b`` is written: stamp it, make it the newest, and keep the cycle's timing."""
        close_buffer(self._h, 0, b, stamp_ns, True)
        note_timing(self._n_timing, self._timing, exec_us, jitter_us)   # once per cycle, for the histograms

    def inputs(self) -> FromPlc:
        """The PLC's values, consistent with one write; the last good copy if the I/O side kept writing."""
        (o0, o1), copy = self._off_in, self._in_copy
        if read_newest(self._h, 5, o0, o1, self._in_bytes, self._mem, self._in_scratch, copy):
            self._last_inputs = r = self._read_inputs(self._unpack_in(copy, 0))
            return r
        if self._last_inputs is None:          # before the first cycle only: a copy must exist
            got = None
            while got is None:
                got = self._copy("from_plc", 0, self.in_codec.words)
            self._last_inputs = self._read_inputs(self.in_codec.decode(got[2]))
            return self._last_inputs
        self.stale_reads += 1
        return self._last_inputs

    def outputs(self) -> dict[str, float]:
        """The newest to_plc values by name (logs, tests, tools); after `close`, the last this side published."""
        if self._h is None:
            return dict(zip(self.out_codec.names, self.out_codec.pick(self._last_record)))
        got = None
        while got is None:
            got = self._copy("to_plc", 0, self.out_codec.words)
        return dict(zip(self.out_codec.names, self.out_codec.decode(got[2])))

    # -- the I/O side ---------------------------------------------------------------------------
    def snapshot(self) -> tuple[int, int, list[int], list[int]]:
        """(version, stamp_ns, to_plc words, from_plc words) of one consistent cycle (whole blocks)."""
        got = None
        while got is None:
            got = self._copy("to_plc", 0, self.tables["to_plc"][2])
        return got[0], got[1], got[2], list(self._inputs_master())

    def _inputs_master(self) -> list[int]:
        if self._master is None:
            got = None
            while got is None:
                got = self._copy("from_plc", 0, self.tables["from_plc"][2])
            self._master = got[2]
        return self._master

    def take_over_inputs(self) -> None:
        """Become the from_plc writer after another one (an I/O process restarted after one that died).

        A writer killed between its two sequence increments leaves its buffer's count odd; the next
        writer would then leave it odd after each write, and the cycle would keep a stale copy every
        other write. Make both counts even again (there is no other writer now)."""
        h, k = self._h, _H["from_plc"]
        for b in (0, 1):
            if int(h[k + 1 + b]) & 1:
                h[k + 1 + b] += 1
        self._master = None

    def timings_since(self, n: int) -> tuple[int, np.ndarray]:
        """(count now, the (exec_us, jitter_us) rows published since count ``n``, at most `TIMING_RING`)."""
        now = int(self._n_timing[0])
        k = max(n, now - TIMING_RING + 1)
        idx = np.arange(k, now) % TIMING_RING
        return now, self._timing[idx].copy()

    def read(self, table: str, address: int, count: int) -> list[int] | None:
        """Words at [address, address + count) of ``table``, or None if outside every block."""
        for d, (tab, start, size) in self.tables.items():
            if tab == table and start <= address and address + count <= start + size:
                if d == "from_plc":
                    return self._inputs_master()[address - start: address - start + count]
                got = None
                while got is None:
                    got = self._copy(d, address - start, address - start + count)
                return got[2]
        return None

    def write(self, table: str, address: int, values: list[int]) -> bool:
        """Write the PLC's registers; False (and no change) if any word is not the PLC's to write, or the
        write starts or ends inside a multi-word register."""
        end = address + len(values)
        tab, start, _ = self.tables["from_plc"]
        if (table != tab or not values or any(a not in self.writable for a in range(address, end))
                or address in self.inner or end in self.inner):
            self.refused_writes += 1
            return False
        master = self._inputs_master()
        master[address - start: end - start] = [int(v) & 0xFFFF for v in values]
        self._publish("from_plc", master)
        return True

    def write_block(self, words: list[int]) -> None:
        """Replace the from_plc block's leading words (the client role: what it read from the PLC)."""
        master = self._inputs_master()
        master[: len(words)] = [int(v) & 0xFFFF for v in words]
        self._publish("from_plc", master)

    def write_values(self, values: dict[str, float]) -> None:
        """Set named from_plc values and publish the block: the initial joints before the I/O side starts, and
        the robot road's joints of each packet (with the command word and heartbeat when no PLC writes them).
        Names the map leaves out are skipped."""
        codec, master = self.in_codec, self._inputs_master()
        current = codec.decode(master)
        for name, v in values.items():
            k = codec.index.get(name)
            if k is not None:
                current[k] = v
        master[: codec.words] = codec.encode(current)
        self._publish("from_plc", master)

    def to_plc_words(self) -> list[int]:
        """The to_plc block's mapped words (the client role writes them into the PLC)."""
        got = None
        while got is None:
            got = self._copy("to_plc", 0, self.out_codec.words)
        return got[2]

    # -- life cycle -----------------------------------------------------------------------------
    def close(self) -> None:
        """Detach; the creating process also frees the memory. The arrays over it go first: after this they
        would point at memory no longer mapped. An image collected without `close` is closed then."""
        self._h = self._n_timing = self._timing = self._mem = self.bytes = None
        self._buf = {}
        self._release()


def release(shm: SharedMemory, owner: bool, views=()) -> None:
    """Detach from a shared memory block; its creator (``owner``) also frees the name. ``views``: the
    memoryviews over its buffer (slices, casts), released first: one left alive keeps the mapping, and
    SharedMemory's own finalizer then fails on it ("cannot close exported pointers exist"). The process image
    and the trace ring (`service.trace`) let theirs go so, on `close` or when collected without it."""
    for view in views:
        view.release()
    if owner:               # first: a view still alive (BufferError below) must not keep the name
        try:
            shm.unlink()
        except FileNotFoundError:
            pass
    try:
        shm.close()
    except BufferError:
        pass  # a view is still alive somewhere; the mapping goes when it does
