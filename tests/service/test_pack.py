"""The compiled packer (`service.kernel.pack`) writes and reads the bytes `struct` does: the PLC's blocks as
`BlockCodec` packs them (scaled integers rounded half to even and clamped, NaN and inf as 0; float32 and its
range) and the trace's row as `service.trace` packs it. The packer leaves a block's pads as they are (zero in
the process image, where nothing else is ever written); around the block it writes nothing."""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from plc_link.register_map import BlockCodec, Register, struct_fields
from service.kernel.pack import pack, scratch, table, unpack
from service.trace import _ROW

KINDS = ("uint16", "int16", "uint32", "int32", "float32")
SCALES = (1.0, 10.0, 0.01)
# the edges: halves (ties to even), the types' ranges and beyond, non-finite values, float32's range
EDGES = [0.0, -0.0, 0.5, 1.5, 2.5, -0.5, -1.5, -2.5, 0.49999999999999994, 65535.0, 65535.4, 65535.5, 65536.0,
         -32768.0, -32768.5, -32769.0, 32767.5, 4294967295.0, 4294967295.5, 4294967296.0, 2147483647.5,
         -2147483648.5, -1e300, 1e300, math.nan, math.inf, -math.inf, 3.4028234e38, -3.4028234e38, 1e-46, 12.345]


def codec(kinds: list[str], scales: list[float]) -> BlockCodec:
    regs, address = [], 100
    for k, (kind, scale) in enumerate(zip(kinds, scales)):
        count = 2 if kind.endswith("32") else 1
        regs.append(Register(f"r{k}", "input_registers", address, kind, count, "", scale, "to_plc"))
        address += count + k % 2                # a gap now and then (padding words)
    return BlockCodec(regs, 100, address - 100)


def packed(c: BlockCodec, values: list[float]) -> tuple[bytes, bytes]:
    """(struct's bytes, the compiled packer's bytes) of ``values``; struct's is None when it refuses."""
    n = 2 * c.words
    V = np.array([7.0, *values])                # the values from place 1 in the vector
    rows, scales = table(c.fields(), list(range(1, len(values) + 1)))
    mem = np.full(n + 6, 0xAB, dtype=np.uint8)
    mem[3:3 + n] = 0                            # the block's pads are zero (the packer leaves them as they are)
    ok = pack(V, rows, scales, scratch(), mem, 3)
    ref = bytearray(b"\xab" * 3 + bytes(n) + b"\xab" * 3)
    try:
        c.pack_into(ref, 3, values)
    except OverflowError:
        ref = None
    return (None if ref is None else bytes(ref)), (bytes(mem) if ok else None)


@pytest.mark.parametrize(("kind", "scale"), [(k, s) for k in KINDS for s in SCALES if k != "float32" or s == 1.0])
def test_each_kind_packs_the_edges_as_struct_does(kind, scale):
    c = codec([kind], [scale])
    for x in EDGES:
        ref, got = packed(c, [x])
        assert got == ref, (kind, scale, x)


def test_a_mixed_block_of_random_values_packs_and_unpacks_as_struct_does():
    rng = np.random.default_rng(25)
    kinds = list(rng.choice(KINDS, 40))
    scales = [1.0 if k == "float32" else float(rng.choice(SCALES)) for k in kinds]
    c = codec(kinds, scales)
    for _ in range(200):
        values = list(rng.normal(0.0, 10.0 ** rng.uniform(0, 6), len(kinds)))
        values[int(rng.integers(len(kinds)))] = float(rng.choice(EDGES))
        ref, got = packed(c, values)
        assert got == ref
        if ref is None:
            continue
        back = np.zeros(len(kinds) + 1)
        rows, sc = table(c.fields(), list(range(1, len(kinds) + 1)))
        unpack(back, rows, sc, scratch(), np.frombuffer(ref, dtype=np.uint8), 3)
        expected = c.unpack_from(ref, 3)
        assert [float(v) for v in back[1:]] == pytest.approx(list(expected), rel=0, abs=0, nan_ok=True)


def test_a_field_the_block_does_not_hold_unpacks_as_zero():
    c = codec(["uint16", "float32"], [1.0, 1.0])
    fields = c.fields()
    rows, sc = table([fields[0], None, fields[1]], [1, 2, 3])
    buf = bytearray(2 * c.words)
    c.pack_into(buf, 0, [5, 2.5])
    V = np.full(4, 9.0)
    unpack(V, rows, sc, scratch(), np.frombuffer(bytes(buf), dtype=np.uint8), 0)
    assert list(V) == [9.0, 5.0, 0.0, 2.5]


def test_the_trace_row_packs_as_struct_does():
    rng = np.random.default_rng(7)
    row = [(code, offset, 1.0) for code, offset in struct_fields(_ROW.format)]
    rows, sc = table(row, list(range(len(row))))
    for _ in range(50):
        values = [float(rng.normal(0, 100))] + list(rng.normal(0, 50, 24)) + list(rng.integers(0, 0xFFFF, 4).astype(float))
        values[int(rng.integers(1, 25))] = float(rng.choice([math.nan, math.inf, -math.inf, 0.5, -2.5]))
        mem = np.zeros(_ROW.size, dtype=np.uint8)
        assert pack(np.array(values), rows, sc, scratch(), mem, 0)
        ref = _ROW.pack(values[0], *values[1:25], *(int(v) for v in values[25:]))
        assert bytes(mem) == ref


def test_struct_fields_reads_offsets_and_pads():
    assert struct_fields("<d2fxxH") == [("d", 0), ("f", 8), ("f", 12), ("H", 18)]
    assert len(struct_fields(_ROW.format)) == 29 and struct_fields(_ROW.format)[-1] == ("H", 110)
    with pytest.raises(ValueError):
        struct_fields("=dH")
    assert struct.calcsize(_ROW.format) == 112
