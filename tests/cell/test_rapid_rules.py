"""The RAPID writer's rules (cell/robot/rapid.py) fail on the old shipped probe module (tests/data/robot/old/): its
touch line and its probe frame's header line build strings over 80 characters, and its ERROR handler closes the log
only for ERR_WHLSEARCH. NumToStr's widest text, as the checker counts it, bounds what the controller builds."""

from __future__ import annotations

import pytest
from hypothesis import given
from hypothesis import strategies as st

from cell.robot.probe_rapid import BOUNDS
from cell.robot.rapid import MAX_IDENTIFIER, RapidWriter, longest, numtostr_width, rapid_violations
from cell.robot.rules import ProgramRuleError
from testlib.common import ROOT
from testlib.robot_logs import rapid_string

OLD = ROOT / "tests" / "data" / "robot" / "old"


def module(*body: str) -> str:
    return "MODULE M\n    PROC P()\n" + "\n".join(f"        {b}" for b in body) + "\n    ENDPROC\nENDMODULE\n"


def test_the_old_probe_module_builds_strings_over_80_and_leaves_the_log_open():
    text = (OLD / "StiffCompProbe.modx").read_text()
    lines = text.splitlines()
    found = {(v.rule, v.line) for v in rapid_violations(text, BOUNDS)}
    header = next(n for n, t in enumerate(lines, 1) if '"# probe_frame: {xyz_mm: ["' in t)
    touch = next(n for n, t in enumerate(lines, 1) if "NumToStr(k, 0)" in t)
    proc = next(n for n, t in enumerate(lines, 1) if "PROC StiffCompProbe()" in t)
    assert found == {("string", header), ("string", touch), ("handler", proc)}


def test_the_old_touch_line_is_over_80_at_the_first_touch():
    """What the controller builds for the old touch line at an ordinary pose: ERR_STRTOOLNG at touch 1."""
    text = (OLD / "StiffCompProbe.modx").read_text()
    start = text.index("Write log, NumToStr(k, 0)")
    expr = text[start + len("Write log, "):text.index(";", start)]
    env = {"k": 1, "dx": 0.984808, "dy": 0.173648}
    env.update({f"jHit.robax.rax_{i}": v for i, v in enumerate([10.5, -60.25, 90.125, -0.5, 60.75, 170.5], 1)})
    assert len(rapid_string(expr, env)) > 80


def test_the_writer_refuses_the_old_module():
    with pytest.raises(ProgramRuleError) as e:
        RapidWriter("StiffCompProbe.modx", BOUNDS).add((OLD / "StiffCompProbe.modx").read_text()).render()
    assert "string" in str(e.value) and "handler" in str(e.value)


@given(st.floats(-99999.0, 99999.0, allow_nan=False), st.integers(0, 8))
def test_numtostr_width_bounds_the_text(value, decimals):
    """NumToStr(v, d) for any |v| within the default bound is never wider than the checker counts."""
    assert len(rapid_string(f"NumToStr(v, {decimals})", {"v": value})) <= numtostr_width("v", decimals, {})


def test_a_chain_is_measured_at_its_longest():
    assert longest('"ab" + NumToStr(x, 2) + "c"', {}, {"x": 9.0}) == 2 + (1 + 1 + 1 + 2) + 1
    assert longest('"ab" + NAME', {"NAME": "xyz"}, {}) == 5
    assert longest("a + b", {}, {}) is None
    assert longest('"ab" + unknown', {}, {}) > 80          # a string of unknown length is refused


def test_strings_up_to_80():
    assert rapid_violations(module(f'TPWrite "{"x" * 80}";')) == []
    assert [v.rule for v in rapid_violations(module(f'TPWrite "{"x" * 81}";'))] == ["string"]
    assert [v.rule for v in rapid_violations(module(f'Write log, "{"x" * 70}" \\Num:=n;'))] == ["string"]


def test_identifiers_up_to_32():
    assert rapid_violations(module(f"{'a' * MAX_IDENTIFIER} := 1;")) == []
    assert [v.rule for v in rapid_violations(module(f"{'a' * (MAX_IDENTIFIER + 1)} := 1;"))] == ["identifier"]


@pytest.mark.parametrize("handler, ok", [
    (["Close log;", "EXIT;"], True),
    (["Close log;", 'TPWrite "stopped" \\Num:=ERRNO;', "EXIT;"], True),
    (["IF ERRNO = ERR_WHLSEARCH THEN", "Close log;", "EXIT;", "ENDIF"], False),
    (["Close log;", "Stop;"], False),
    ([], False),
])
def test_a_routine_that_opens_a_file_closes_it_on_every_error(handler, ok):
    text = module('Open "HOME:/a.csv", log \\Write;', "Close log;", *(["ERROR"] + handler if handler else []))
    assert ([v.rule for v in rapid_violations(text)] == []) is ok
