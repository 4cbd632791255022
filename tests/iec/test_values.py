"""The structured-text runtime (`st_runtime`): IEC's typing rules, the PLC's arithmetic, the standard timers and
the struct layout, each on a small program written with the generator's own model and rendered as a TwinCAT
file (so blark parses what it parses in the library)."""

from __future__ import annotations

import math
import struct
from decimal import ROUND_HALF_EVEN, Decimal

import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from cell.plc.model import (
    BOOL,
    DINT,
    INT,
    REAL,
    TIME,
    UINT,
    WORD,
    ArrayType,
    Derived,
    Enum,
    Gvl,
    Pou,
    Struct,
    Var,
    VarList,
)
from cell.plc.twincat import object_file
from st_runtime import Runtime, StError, f32, load


class NoNetwork:
    def duration(self, kind, now):
        raise AssertionError("no request in these programs")


def program(tmp_path, body: str, local: tuple[Var, ...], *types, runtime: Runtime | None = None):
    """MAIN with ``local`` variables and ``body``, beside ``types``; a fresh instance of it."""
    files = []
    for obj in (*types, Pou("MAIN", "PROGRAM", (VarList("VAR", local),), body)):
        name, data = object_file(obj)
        (tmp_path / name).write_bytes(data)
        files.append(tmp_path / name)
    machine = load(files, runtime or Runtime(NoNetwork()))
    return machine, machine.instance("MAIN")


NUMBERS = (Var("n", UINT), Var("k", INT), Var("d", DINT), Var("w", WORD), Var("r", REAL), Var("b", BOOL))


@pytest.mark.parametrize(("body", "why"), [
    ("n := n AND 1;", "AND on UINT"),                       # IEC: AND takes BOOL or bit strings
    ("b := (n OR 2) <> 0;", "OR on UINT"),
    ("w := n;", "UINT assigned to WORD"),
    ("r := d;", "DINT assigned to REAL"),                   # not implicit: a DINT does not fit a REAL
    ("k := n;", "UINT assigned to INT"),
    ("n := r;", "REAL assigned to UINT"),
    ("r := UINT_TO_REAL(k);", "UINT_TO_REAL of INT"),
    ("IF n THEN b := TRUE; END_IF", "a condition of UINT"),
])
def test_what_iec_does_not_convert_implicitly_is_refused_with_its_line(tmp_path, body, why):
    with pytest.raises(StError, match=why) as e:
        program(tmp_path, body, NUMBERS)
    assert "MAIN: line" in str(e.value)


def test_an_enum_takes_only_its_own_values(tmp_path):
    state = Enum("E_State", UINT, (("A", 0, ""), ("B", 1, "")))
    local = (*NUMBERS, Var("e", Derived("E_State")))
    with pytest.raises(StError, match="UINT assigned to E_State"):
        program(tmp_path, "e := n;", local, state)
    _, main = program(tmp_path, "CASE n OF 1: e := E_State.B; END_CASE", local, state)
    main.n = 1
    main.body()
    assert main.e == 1


def test_what_iec_converts_implicitly_runs(tmp_path):
    _, main = program(tmp_path, "d := n; r := k; w := WORD#16#F0F0 AND UINT_TO_WORD(n); b := (w AND 16#0010) <> 0;",
                      NUMBERS)
    main.n, main.k = 0x0011, -3
    main.body()
    assert (main.d, main.r, main.w, main.b) == (0x11, -3.0, 0x10, True)


@given(st.integers(0, 0xFFFF), st.integers(-0x8000, 0x7FFF), st.integers(-100000, 100000))
@settings(max_examples=30, deadline=None)
def test_integers_wrap_at_their_width(tmp_path_factory, n, k, add):
    _, main = _wrapping(tmp_path_factory)
    main.n, main.k, main.d = n, k, add
    main.body()
    assert main.n == (n + add) & 0xFFFF
    assert main.k == ((k + add + 0x8000) & 0xFFFF) - 0x8000


_made = {}


def _wrapping(factory):
    if "wrap" not in _made:
        _made["wrap"] = program(factory.mktemp("wrap"), "n := DINT_TO_UINT(UINT_TO_DINT(n) + d); "
                                "k := DINT_TO_INT(INT_TO_DINT(k) + d);", NUMBERS)
    return _made["wrap"]


@given(st.one_of(st.floats(-1e6, 1e6, allow_nan=False), st.integers(-1000, 1000).map(lambda k: k / 6)))
@example(2.5 / 3)
@example(-2.5 / 3)
@settings(max_examples=30, deadline=None)
def test_real_is_float32_and_real_to_int_rounds_half_to_even(tmp_path_factory, x):
    """x86's conversion rounds a tie to the even integer (and so does MATIEC): 2.5 -> 2, -2.5 -> -2, 4.5 -> 4
    (`st_runtime.values.real_to_int`; tests/iec/test_real_semantics.py holds every type and value)."""
    if "real" not in _made:
        _made["real"] = program(tmp_path_factory.mktemp("real"),
                                "r := r * 3.0; d := REAL_TO_DINT(LIMIT(-2147483520.0, r, 2147483520.0));", NUMBERS)
    _, main = _made["real"]
    main.r = f32(x)
    main.body()
    assert main.r == f32(f32(x) * 3.0)
    assert main.d == int(Decimal(main.r).to_integral_value(rounding=ROUND_HALF_EVEN))
    if main.r in (2.5, -2.5):
        assert main.d == math.copysign(2, main.r)


def test_ton_and_tp_follow_the_clock(tmp_path):
    runtime = Runtime(NoNetwork())
    local = (Var("ton", Derived("TON")), Var("tp", Derived("TP")), Var("b", BOOL), Var("q", BOOL), Var("p", BOOL),
             Var("t", TIME, "T#20MS"))
    _, main = program(tmp_path, "ton(IN := b, PT := t); tp(IN := b, PT := t); q := ton.Q; p := tp.Q;", local,
                      runtime=runtime)
    seen = []
    for now in range(60):
        runtime.now_ms = now
        main.b = 5 <= now < 45
        main.body()
        seen.append((main.q, main.p))
    assert [now for now, (q, _) in enumerate(seen) if q] == list(range(25, 45))     # IN for PT, then until IN drops
    assert [now for now, (_, p) in enumerate(seen) if p] == list(range(5, 25))      # PT from the rising edge


def test_structs_copy_into_their_target_and_lay_out_as_twincat(tmp_path):
    natural = Struct("ST_Natural", (Var("a", UINT), Var("x", REAL), Var("c", ArrayType(1, 2, WORD))))
    packed = Struct("ST_Packed", (Var("a", UINT), Var("x", REAL), Var("c", ArrayType(1, 2, WORD))), pack=True)
    local = (Var("s", Derived("ST_Natural")), Var("t", Derived("ST_Natural")), Var("p", Derived("ST_Packed")),
             Var("i", INT))
    machine, main = program(tmp_path, "t := s; FOR i := 1 TO 2 DO s.c[i] := INT_TO_WORD(i); END_FOR", local,
                            natural, packed)
    target = main.t
    main.s.a, main.s.x = 7, 1.5
    main.body()
    assert main.t is target and (main.t.a, main.t.x) == (7, 1.5) and main.s.c == [1, 2]
    assert machine.layout("ST_Natural").size == 12              # a UINT, 2 bytes of padding, a REAL, two WORDs
    assert machine.layout("ST_Packed").size == 10
    assert main.s.to_bytes() == struct.pack("<H2xfHH", 7, 1.5, 1, 2)
    main.p.from_bytes(struct.pack("<HfHH", 3, -2.0, 4, 5))
    assert (main.p.a, main.p.x, main.p.c) == (3, -2.0, [4, 5])


def test_a_constant_cannot_be_written_and_an_unknown_name_is_named(tmp_path):
    gvl = Gvl("GVL_K", (VarList("VAR_GLOBAL", (Var("K", UINT, "5"),), constant=True),))
    _, main = program(tmp_path, "n := GVL_K.K;", NUMBERS, gvl)
    main.body()
    assert main.n == 5
    with pytest.raises(StError, match="GVL_K.K is a constant"):
        program(tmp_path, "GVL_K.K := 1;", NUMBERS, gvl)
    with pytest.raises(StError, match="nope is not declared"):
        program(tmp_path, "nope := 1;", NUMBERS)
