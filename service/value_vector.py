"""The compiled service's values: one float vector that the compiled code reads and writes, its places named.

    [ head | task | signals | t | inputs | scales ]

* head: the steady cycle's mirror of the Python objects' state, its inputs and the offsets of the parts below
  (`service.kernel.steady_cycle.HEAD`; at most `HEAD_ROOM` places);
* task: the task's counters of the cycle (`plc_link.contract.TaskValues`, ``task.NAME``);
* signals: the cycle's Signals (`service.signals.SIGNAL_SLOTS`, ``signals.NAME`` or ``signals.NAME[k]``), the
  cycle's own vector (`Cycle.vector` is this part);
* t: the cycle's time, and inputs: the PLC's values (`FromPlc`, ``inputs.NAME``; ``q1`` .. ``q6`` too), for
  the trace's row;
* scales: of the PLC's two blocks (`service.kernel.pack.table`).

The contract's values for the PLC are found here by their sources (`Producer.indices`), the trace's row by
`service.trace.ROW_SOURCES`. The packers and the steady cycle come with the compiled path (`compiled`),
which loads numba.
"""

from __future__ import annotations

from functools import partial

import numpy as np

from plc_link.contract import TO_PLC, FromPlc, TaskValues
from plc_link.register_map import struct_fields

from .signals import SIGNAL_SIZE, SIGNAL_SLOTS
from .trace import ROW_SOURCES

HEAD_ROOM = 64


class Values:
    """The vector ``V`` and its places (``slots``: name -> place; ``at``: where each part starts).

    Parameters
    ----------
    n_scales : int
        Room for the scales of the PLC's blocks (one per register of both).
    """

    def __init__(self, n_scales: int):
        at = self.at = {"task": HEAD_ROOM}
        at["signals"] = at["task"] + len(TaskValues._fields)
        at["t"] = at["signals"] + SIGNAL_SIZE
        at["inputs"] = at["t"] + 1
        at["scales"] = at["inputs"] + len(FromPlc._fields)
        slots = {f"task.{n}": at["task"] + k for k, n in enumerate(TaskValues._fields)}
        for name, (o, n) in SIGNAL_SLOTS.items():
            base = at["signals"] + o
            slots.update({f"signals.{name}": base} if n == 1 else {f"signals.{name}[{i}]": base + i for i in range(n)})
        slots["t"] = at["t"]
        slots.update({f"inputs.{n}": at["inputs"] + k for k, n in enumerate(FromPlc._fields)})
        slots.update({f"q{i}": slots[f"inputs.q{i}"] for i in range(1, 7)})
        self.slots = slots
        self.V = np.zeros(at["scales"] + n_scales)
        self.signals = self.V[at["signals"]:at["signals"] + SIGNAL_SIZE]
        self.task = memoryview(self.V[at["task"]:at["task"] + len(TaskValues._fields)]).cast("B").cast("d")
        self._tq = memoryview(self.V[at["t"]:at["inputs"] + len(FromPlc._fields)]).cast("B").cast("d")
        self._q = [1 + FromPlc._fields.index(f"q{i}") for i in range(1, 7)]

    def put_t_q(self, t: float, q: list[float]) -> None:
        """The cycle's time and the PLC's joints (the trace's row reads them here)."""
        tq, (a, b, c, d, e, f) = self._tq, self._q
        tq[0], tq[a], tq[b], tq[c], tq[d], tq[e], tq[f] = t, *q

    def compiled(self, service, to_plc: list[int]):
        """The packers (image, trace: each a function (memory, offset) -> bool) and the steady cycle of the
        compiled ``service`` (`service.steady`), loaded now (numba's cache), not in a cycle. ``to_plc``: where
        each `TO_PLC` value lies (`Producer.indices`)."""
        from .kernel.pack import pack, scratch, table
        from .steady import SteadyCycle

        out_codec, in_codec = service.image.out_codec, service.image.in_codec
        where = dict(zip((v.name for v in TO_PLC), to_plc))
        out = table(out_codec.fields(), [where[n] for n in out_codec.names])
        fields = dict(zip(in_codec.names, in_codec.fields()))
        inp = table([fields.get(n) for n in FromPlc._fields], [self.slots[f"inputs.{n}"] for n in FromPlc._fields])
        tmp = scratch()
        image = partial(pack, self.V, *out, tmp)
        image(np.zeros(2 * out_codec.words, dtype=np.uint8), 0)        # the first call loads it: not in a cycle
        trace = None
        if service.trace is not None:
            from .trace import _ROW

            row = [(code, offset, 1.0) for code, offset in struct_fields(_ROW.format)]
            trace = partial(pack, self.V, *table(row, [self.slots[n] for n in ROW_SOURCES]), tmp)
        return (image, trace), SteadyCycle(service, self, inp, out)
