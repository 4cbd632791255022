"""What the runtime computes from any REAL or LREAL, NaN and the infinities included, where a PLC keeps running:
REAL_TO_<int> rounds half to even and gives the x86 conversion's value for what does not fit; LIMIT, MIN and
MAX compare as MATIEC's C does; REAL overflows to an infinity and divides by zero as IEEE 754 does. The
expected values are computed here independently of `st_runtime.values` (decimal rounding, the C expressions
written out), each against its source in the docstrings of `st_runtime.values`."""

from __future__ import annotations

import math
import struct
from decimal import ROUND_HALF_EVEN, Decimal

from hypothesis import example, given, settings
from hypothesis import strategies as st
from test_values import program

from cell.plc.model import REAL, Derived, Elementary, Struct, Var
from st_runtime import f32

WIDTHS = {"SINT": (8, True), "INT": (16, True), "DINT": (32, True), "LINT": (64, True), "USINT": (8, False),
          "UINT": (16, False), "UDINT": (32, False), "ULINT": (64, False), "BYTE": (8, False), "WORD": (16, False),
          "DWORD": (32, False), "LWORD": (64, False)}
LREAL = Elementary("LREAL")
SPECIAL = (math.nan, math.inf, -math.inf, -0.0, 0.5, -0.5, 2.5, -2.5, 3.5, 1e300, -1e300, 2.0 ** 63, -2.0 ** 63,
           2.0 ** 63 - 1024, 9.3e18, 3.4028234663852886e38)
_made: dict = {}


def expected(x: float, t: str) -> int:
    """``<REAL>_TO_t(x)`` by the rule docs/plc.md states, computed with decimal arithmetic: round half to even
    to a 64-bit integer, NaN/inf/out of 64 bits the integer indefinite 0x8000_0000_0000_0000, then the type's
    low bits (two's complement for a signed type)."""
    n = -(1 << 63)
    if math.isfinite(x):
        r = int(Decimal(x).to_integral_value(rounding=ROUND_HALF_EVEN))
        n = r if -(1 << 63) <= r < (1 << 63) else n
    width, signed = WIDTHS[t]
    n &= (1 << width) - 1
    return n - (1 << width) if signed and n >> (width - 1) else n


def _conversions(factory):
    if "conv" not in _made:
        local = (Var("r", REAL), Var("l", LREAL), *(Var(f"r{t}", Elementary(t)) for t in WIDTHS),
                 *(Var(f"l{t}", Elementary(t)) for t in WIDTHS))
        body = " ".join(f"r{t} := REAL_TO_{t}(r); l{t} := LREAL_TO_{t}(l);" for t in WIDTHS)
        _made["conv"] = program(factory.mktemp("conv"), body, local)
    return _made["conv"][1]


@given(st.one_of(st.sampled_from(SPECIAL), st.floats(), st.floats(width=32)))
@example(math.nan)
@example(math.inf)
@settings(max_examples=300, deadline=None)
def test_no_real_or_lreal_makes_a_conversion_raise_and_each_result_is_in_its_type(tmp_path_factory, x):
    main = _conversions(tmp_path_factory)
    main.r, main.l = f32(x), x
    main.body()                                        # never an exception
    for t, (width, signed) in WIDTHS.items():
        lo, hi = (-(1 << (width - 1)), (1 << (width - 1)) - 1) if signed else (0, (1 << width) - 1)
        for prefix, value in (("r", f32(x)), ("l", x)):
            got = getattr(main, f"{prefix}{t}")
            assert lo <= got <= hi, (prefix, t, x, got)
            assert got == expected(value, t), (prefix, t, x, got)


def test_nan_and_the_infinities_convert_to_the_documented_values(tmp_path_factory):
    """0 for every type up to 32 bits (what MATIEC gives for NaN); the indefinite's bits for 64."""
    main = _conversions(tmp_path_factory)
    for x in (math.nan, math.inf, -math.inf, 1e30):
        main.r = main.l = f32(x)
        main.body()
        assert {t: getattr(main, f"r{t}") for t in WIDTHS} == {
            **{t: 0 for t in WIDTHS if WIDTHS[t][0] <= 32}, "LINT": -(1 << 63), "ULINT": 1 << 63, "LWORD": 1 << 63}


@given(st.integers(-(1 << 22), 1 << 22))
@settings(max_examples=60, deadline=None)
def test_a_tie_rounds_to_the_even_integer(tmp_path_factory, k):
    """x86's conversion and MATIEC: 2.5 -> 2, 3.5 -> 4, -2.5 -> -2 (k + 0.5 is a REAL exactly here)."""
    main = _conversions(tmp_path_factory)
    main.r = main.l = k + 0.5
    main.body()
    even = k if k % 2 == 0 else k + 1
    assert main.rDINT == main.lDINT == main.rLINT == even


def matiec_limit(mn, x, mx):
    """MATIEC's LIMIT, its C expression ``IN > MN ? IN < MX ? IN : MX : MN`` written out."""
    if not x > mn:
        return mn
    if x < mx:
        return x
    return mx


def matiec_min(op1, tmp):
    """One step of MATIEC's MIN: ``op1 > tmp ? tmp : op1``."""
    if op1 > tmp:
        return tmp
    return op1


def matiec_max(op1, tmp):
    """One step of MATIEC's MAX: ``op1 < tmp ? tmp : op1``."""
    if op1 < tmp:
        return tmp
    return op1


def same(a: float, b: float) -> bool:
    return (math.isnan(a) and math.isnan(b)) or a == b


BOUNDS = st.one_of(st.just(math.nan), st.floats(-1e6, 1e6, width=32))


@given(st.one_of(st.sampled_from((math.nan, math.inf, -math.inf)), st.floats(width=32)), BOUNDS, BOUNDS)
@example(math.nan, -1.0, 1.0)
@settings(max_examples=200, deadline=None)
def test_limit_min_and_max_of_a_nan_are_matiecs(tmp_path_factory, x, a, b):
    if "sel" not in _made:
        local = tuple(Var(n, REAL) for n in ("x", "a", "b", "lim", "mn1", "mn2", "mx1", "mx2"))
        _made["sel"] = program(tmp_path_factory.mktemp("sel"), "lim := LIMIT(a, x, b); mn1 := MIN(x, a); "
                               "mn2 := MIN(a, x); mx1 := MAX(x, a); mx2 := MAX(a, x);", local)
    main = _made["sel"][1]
    main.x, main.a, main.b = f32(x), f32(a), f32(b)
    main.body()
    x, a, b = main.x, main.a, main.b
    assert same(main.lim, matiec_limit(a, x, b))
    assert same(main.mn1, matiec_min(x, a)) and same(main.mn2, matiec_min(a, x))
    assert same(main.mx1, matiec_max(x, a)) and same(main.mx2, matiec_max(a, x))


def test_limit_of_a_nan_is_the_lower_bound_and_a_rate_limit_stays_finite(tmp_path):
    """MAIN's rate limit, ``applied := applied + LIMIT(-step, target - applied, step)``: a NaN target moves the
    applied value one step down (LIMIT gives MN), it never makes it NaN."""
    local = tuple(Var(n, REAL) for n in ("x", "lim", "applied", "target", "step"))
    _, main = program(tmp_path, "lim := LIMIT(-1.0, x, 1.0); applied := applied + LIMIT(-step, target - applied, "
                      "step);", local)
    main.x, main.applied, main.target, main.step = math.nan, 0.5, math.nan, 0.002
    for _ in range(3):
        main.body()
    assert main.lim == -1.0
    assert main.applied == f32(f32(f32(0.5 - 0.002) - 0.002) - 0.002)


def test_real_overflows_to_an_infinity_and_divides_by_zero_as_ieee_754(tmp_path):
    """A REAL product past the largest REAL is an infinity (it was a float64 no record could hold), and a REAL
    divided by zero an infinity or NaN (as MATIEC's C runs, the exceptions masked), not a Python exception."""
    rec = Struct("ST_R", (Var("x", REAL),))
    local = (Var("r", REAL), Var("z", REAL), Var("q", REAL), Var("n", REAL), Var("l", LREAL), Var("lq", LREAL),
             Var("s", Derived("ST_R")))
    _, main = program(tmp_path, "r := r * 10.0; s.x := r; q := 1.0 / z; n := z / z; lq := -l / z;", local, rec)
    main.r, main.l = 3.0e38, 2.0
    main.body()
    assert (main.r, main.q, main.lq) == (math.inf, math.inf, -math.inf) and math.isnan(main.n)
    assert main.s.to_bytes() == struct.pack("<f", math.inf)
    main.r = 3.4028234663852886e38                 # the largest REAL: times 10 overflows, times 1 does not
    main.body()
    assert main.r == math.inf
