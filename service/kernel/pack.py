"""The cycle's values into the bytes the PLC and the trace read, in one compiled call each (numba).

The compiled service keeps a cycle's values in one float vector (the task's counters, `service.pipeline`'s
Signals, the time and the joints: `service.app`), and a table says, for each field of a packed record,
its kind, where its value lies in the vector and where its bytes go. The tables come from the owners of the
layouts (`plc_link.register_map.BlockCodec.fields` for the PLC's registers, `service.trace` for the
trace's row), and the bytes are what their `struct` packing writes:

* ``f`` float32, ``d`` float64: IEEE, little-endian (a finite value beyond float32's range is refused, as
  `struct` refuses it; nothing is written then);
* ``H``, ``h``, ``I``, ``i``: value times scale, NaN and inf as 0, clamped to the type's range, rounded half
  to even (Python's `round`), little-endian.

Pad bytes ("x") are not written: they stay as they are (zero in the process image and the trace's ring, where
nothing else writes them). `tests/service/test_pack.py` holds the two packings to the same bytes.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

KINDS = {"f": 0, "d": 1, "H": 2, "h": 3, "I": 4, "i": 5}
_SIZE = (4, 8, 2, 2, 4, 4)
_RANGE = {"H": (0, 0xFFFF), "h": (-0x8000, 0x7FFF), "I": (0, 0xFFFFFFFF), "i": (-0x80000000, 0x7FFFFFFF)}
_FLOAT32_MAX = float(np.finfo(np.float32).max)


def table(fields: list[tuple[str, int, float] | None], places: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """The table `pack` and `unpack` read: ``fields`` (struct code, byte offset, scale) each with its place in
    the vector, ``places[k]`` (None for a field the block does not hold: `unpack` gives it 0). Returns (int64
    rows of kind, place, offset, low, high; float64 scales)."""
    rows = np.zeros((len(fields), 5), dtype=np.int64)
    scales = np.ones(len(fields))
    for k, (field, place) in enumerate(zip(fields, places)):
        if field is None:
            rows[k] = (-1, place, 0, 0, 0)
            continue
        code, offset, scale = field
        lo, hi = _RANGE.get(code, (0, 0))
        rows[k] = (KINDS[code], place, offset, lo, hi)
        scales[k] = scale
    return rows, scales


def scratch() -> np.ndarray:
    """The eight bytes `pack` converts a float through."""
    return np.zeros(1)


@njit(cache=True)
def pack(values, rows, scales, tmp, out, base):
    """Write each field of ``rows`` (`table`) from ``values`` into ``out`` (uint8) at ``base`` + its offset;
    ``tmp``: `scratch`. False, with nothing written, when a float32 field's finite value is beyond float32's
    range."""
    for k in range(rows.shape[0]):
        if rows[k, 0] == 0:
            v = values[rows[k, 1]]
            if math.isfinite(v) and abs(v) > _FLOAT32_MAX and math.isinf(np.float32(v)):
                return False
    f32, f64, i64, u8 = tmp.view(np.float32), tmp, tmp.view(np.int64), tmp.view(np.uint8)
    for k in range(rows.shape[0]):
        kind, v, o = rows[k, 0], values[rows[k, 1]], base + rows[k, 2]
        if kind == 0:
            f32[0] = v
            n = 4
        elif kind == 1:
            f64[0] = v
            n = 8
        else:                           # the low bytes of the int64 are the (two's complement) 16 or 32 bits
            x = v * scales[k]
            i64[0] = 0 if not math.isfinite(x) else round(min(max(x, float(rows[k, 3])), float(rows[k, 4])))
            n = 2 if kind < 4 else 4
        for i in range(n):
            out[o + i] = u8[i]
    return True


@njit(cache=True)
def unpack(values, rows, scales, tmp, src, base):
    """`pack` backwards: each field of ``rows`` read from ``src`` (uint8) at ``base`` + its offset into its place
    in ``values``, integers divided by their scale (what `struct` and `BlockCodec.unpack_from` give); a field of
    kind -1 reads 0."""
    f32, f64, u8 = tmp.view(np.float32), tmp, tmp.view(np.uint8)
    u16, i16, u32, i32 = tmp.view(np.uint16), tmp.view(np.int16), tmp.view(np.uint32), tmp.view(np.int32)
    for k in range(rows.shape[0]):
        kind, o = rows[k, 0], base + rows[k, 2]
        if kind < 0:
            values[rows[k, 1]] = 0.0
            continue
        n = _SIZE[kind]
        for i in range(n):
            u8[i] = src[o + i]
        if kind == 0:
            v = float(f32[0])
        elif kind == 1:
            v = f64[0]
        elif kind == 2:
            v = float(u16[0])
        elif kind == 3:
            v = float(i16[0])
        elif kind == 4:
            v = float(u32[0])
        else:
            v = float(i32[0])
        values[rows[k, 1]] = v if scales[k] == 1.0 else v / scales[k]
