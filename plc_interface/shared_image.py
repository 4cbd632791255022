"""The register image in shared memory, so the Modbus server can run in a process of its own.

In one process the cycle thread and the Modbus thread share the interpreter lock: every request
the server decodes holds it, and the cycle waits. With the server in another process the cycle has
an interpreter to itself; the two meet only in this image, a block of shared memory guarded by a
process-shared lock. Same contract as `RegisterImage`: the cycle publishes and reads whole blocks
under the lock, so a client never sees half of a 32-bit value from one cycle and half from the next.
"""

from __future__ import annotations

import multiprocessing
from multiprocessing.shared_memory import SharedMemory

import numpy as np

from .image import RegisterImage
from .register_map import RegisterMap


class SharedRegisterImage(RegisterImage):
    """A `RegisterImage` whose words live in shared memory; pickles to a handle another process opens.

    Parameters
    ----------
    rmap : RegisterMap
    lock : a multiprocessing lock, optional (made here with the spawn context if not given)
    """

    def __init__(self, rmap: RegisterMap, lock=None, _name: str | None = None):
        super().__init__(rmap)
        layout = [(d, table, start, len(words)) for d, (table, start, words) in self.blocks.items()]
        n_words = sum(n for *_, n in layout)
        size = 8 + 2 * n_words                      # int64 refused-write counter, then the words
        self._owner = _name is None
        self.shm = SharedMemory(name=_name, create=self._owner, size=size)
        self._refused = np.ndarray((1,), dtype=np.int64, buffer=self.shm.buf, offset=0)
        words = np.ndarray((n_words,), dtype=np.uint16, buffer=self.shm.buf, offset=8)
        if self._owner:
            self._refused[0] = 0
            words[:] = 0
        self.blocks, self.by_table, k = {}, {}, 0
        for direction, table, start, n in layout:
            view = words[k:k + n]
            k += n
            self.blocks[direction] = (table, start, view)
            self.by_table.setdefault(table, []).append((start, view))
        self.lock = lock if lock is not None else multiprocessing.get_context("spawn").Lock()

    # The base class counts refused writes in an attribute; here the count is shared.
    @property
    def refused_writes(self) -> int:
        return int(self._refused[0]) if hasattr(self, "_refused") else 0

    @refused_writes.setter
    def refused_writes(self, value: int) -> None:
        if hasattr(self, "_refused"):
            self._refused[0] = value

    def __getstate__(self):
        return {"map": self.map, "lock": self.lock, "name": self.shm.name}

    def __setstate__(self, state):
        self.__init__(state["map"], state["lock"], state["name"])

    def inputs(self) -> list[int]:
        block = self.blocks["from_plc"][2]
        with self.lock:
            return block[: self.in_codec.words].tolist()

    def outputs(self) -> dict[str, float]:
        block = self.blocks["to_plc"][2]
        with self.lock:
            words = block[: self.out_codec.words].tolist()
        return dict(zip(self.out_codec.names, self.out_codec.decode(words)))

    def set_inputs(self, values: dict[str, float]) -> None:
        block = self.blocks["from_plc"][2]
        with self.lock:
            current = self.in_codec.decode(block[: self.in_codec.words].tolist())
            merged = [values.get(n, v) for n, v in zip(self.in_codec.names, current)]
            block[: self.in_codec.words] = self.in_codec.encode(merged)

    def read(self, table: str, address: int, count: int) -> list[int] | None:
        words = super().read(table, address, count)
        return None if words is None else words.tolist()

    def close(self) -> None:
        """Detach; the creating process also frees the memory."""
        for name in ("_refused",):
            self.__dict__.pop(name, None)
        self.blocks, self.by_table = {}, {}
        if self._owner:         # first: a view still alive (BufferError below) must not keep the name
            try:
                self.shm.unlink()
            except FileNotFoundError:
                pass
        try:
            self.shm.close()
        except BufferError:
            pass  # a view is still alive somewhere; the mapping goes when it does
