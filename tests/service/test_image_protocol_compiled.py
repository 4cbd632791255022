"""The process image's read (`plc_link.image.read_newest`) is one implementation: the image's methods run
it over memoryviews, the steady cycle runs it compiled over arrays (`service.kernel.steady_cycle`, where its byte
copy is a loop). Both take the same buffer, or refuse alike, whatever the header says."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plc_link import image
from service.kernel import steady_cycle as ks

N, OFF0, HEADER = 24, 80, 80          # a block of 24 bytes; header of ten int64s; two buffers after it


@settings(max_examples=200, deadline=None)
@given(st.binary(min_size=HEADER + 2 * N, max_size=HEADER + 2 * N),
       st.integers(0, 7), st.integers(0, 7), st.integers(0, 7))
def test_the_compiled_read_is_the_read_in_python(data, version, seq0, seq1):
    mem = bytearray(data)
    h = np.frombuffer(mem, np.int64, 10)
    h[5:8] = version, seq0, seq1                      # direction from_plc: its version and the two sequences
    py_scratch, py_out = bytearray(N), bytearray(b"\xff" * N)
    got_py = image.read_newest(memoryview(h), 5, OFF0, OFF0 + N, N, memoryview(mem), memoryview(py_scratch),
                               memoryview(py_out))
    arr = np.frombuffer(mem, np.uint8)
    work = np.concatenate([np.zeros(N, np.uint8), np.full(N, 0xFF, np.uint8)])
    got_nb = ks.read_newest(h, 5, OFF0, OFF0 + N, N, arr, work[:N], work[N:])
    assert got_nb == got_py
    assert bytes(work[N:]) == bytes(py_out)
    b = version & 1
    seq = (seq0, seq1)[b]
    assert got_py == (seq % 2 == 0)                   # an odd sequence is a buffer being written: refused
    expected = bytes(mem[OFF0 + b * N:OFF0 + (b + 1) * N]) if got_py else b"\xff" * N
    assert bytes(py_out) == expected                  # the newest buffer, or the copy left as it was


def test_the_compiled_copy_refuses_unequal_lengths():
    """A block that runs past the memory is refused, not read beyond it (numba checks no bounds)."""
    with pytest.raises(ValueError, match="lengths differ"):
        ks.read_newest(np.zeros(10, np.int64), 5, OFF0, OFF0 + N, N, np.zeros(HEADER + N - 4, np.uint8),
                       np.zeros(N, np.uint8), np.zeros(N, np.uint8))
