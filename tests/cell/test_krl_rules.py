"""The KRL writer's rules (cell/robot/krl.py) fail on the old shipped programs (tests/data/robot/old/, as they were
before issue 49) for each defect a robot programmer found, and on a small program that breaks one rule, and pass on
the same program mended."""

from __future__ import annotations

import pytest

from cell.robot.krl import MAX_NAME, KrlWriter, krl_violations
from cell.robot.rules import ProgramRuleError
from testlib.common import ROOT

OLD = ROOT / "tests" / "data" / "robot" / "old"


def rules(text: str) -> dict[str, list[int]]:
    out: dict[str, list[int]] = {}
    for v in krl_violations(text):
        out.setdefault(v.rule, []).append(v.line)
    return out


def program(*body: str, sub: str = "") -> str:
    return "DEF Main( )\n" + "\n".join(body) + "\nEND\n" + sub


def line_of(text: str, needle: str) -> int:
    return next(n for n, line in enumerate(text.splitlines(), 1) if needle in line)


def test_the_old_probe_program_breaks_the_escape_the_advance_and_the_file_rules():
    text = (OLD / "StiffCompProbe.src").read_text()
    found = rules(text)
    escaped = [n for n, line in enumerate(text.splitlines(), 1) if '\\n"' in line]
    assert found["escape"] == escaped and len(escaped) == 8
    assert found["advance"] == [line_of(text, "INTERRUPT ON 10")]
    assert found["file"] == [line_of(text, "HALT                      ; no contact")]


def test_the_old_cut_runs_programmed_motions_under_ipo_fast():
    text = (OLD / "StiffCompCut.src").read_text()
    assert rules(text) == {"rsi": [line_of(text, "plunge"), line_of(text, "a slot along X"), line_of(text, "CIRC {"),
                                   line_of(text, "; retract")]}


@pytest.mark.parametrize("name", ["StiffCompProbe.src", "StiffCompCut.src"])
def test_the_writer_refuses_the_old_programs_naming_the_rule_and_the_line(name):
    text = (OLD / name).read_text()
    with pytest.raises(ProgramRuleError) as e:
        KrlWriter(name).add(text.rstrip("\n")).render()
    first = e.value.violations[0]
    assert f"line {first.line}: {first.rule}:" in str(e.value) and name in str(e.value)


def test_names_up_to_24_characters():
    ok = "a" * MAX_NAME
    assert krl_violations(program(f"DECL INT {ok}", f"{ok} = 1")) == []
    long = rules(program(f"DECL INT {ok}b", f"{ok}b = 1"))
    assert long == {"name": [2, 3]}


def test_declarations_before_statements():
    assert krl_violations(program("DECL INT i", "DECL REAL x", "i = 1")) == []
    assert rules(program("DECL INT i", "i = 1", "DECL REAL x")) == {"declaration": [4]}
    assert rules(program("INT i", "i = 1", "REAL x")) == {"declaration": [4]}
    # an INTERRUPT DECL is a statement
    assert krl_violations(program("i = 1", "INTERRUPT DECL 10 WHEN $IN[1]==TRUE DO Main( )")) == []


def test_no_escape_in_a_literal():
    assert rules(program('x = "a\\tb"')) == {"escape": [2]}
    assert krl_violations(program('x = "a b; c"')) == []


@pytest.mark.parametrize("stop, ok", [("", False), ("WAIT SEC 0", True), ("$ADVANCE = 0", True),
                                      ("$OUT[1] = TRUE", False)])
def test_an_interrupt_after_a_motion_needs_an_advance_run_stop(stop, ok):
    body = ["LIN pStart"] + ([stop] if stop else []) + ["INTERRUPT ON 10", "LIN pEnd"]
    assert (krl_violations(program(*body)) == []) is ok
    # a subprogram is entered with its caller's motion still running
    sub = "DEF SEARCH( )\n" + "\n".join(([stop] if stop else []) + ["INTERRUPT ON 10", "LIN pEnd"]) + "\nEND\n"
    assert (rules(program("i = 1", sub=sub)).get("advance") is None) is ok


def test_every_halt_return_and_end_with_the_file_open_is_refused():
    opened = ['CWRITE($FCT_CALL, sw, mw, "krl_fopen", n[], "w", h)', "IF (sw.RET1 <> #CMD_OK) THEN", "  HALT",
              "ENDIF"]
    close = 'CWRITE($FCT_CALL, sw, mw, "krl_fclose", h)'
    assert rules(program(*opened, "IF x THEN", "HALT", "ENDIF", close)) == {"file": [7]}
    assert krl_violations(program(*opened, "IF x THEN", close, "HALT", "RETURN", "ENDIF", close)) == []
    assert rules(program(*opened)) == {"file": [6]}
    closer = f"DEF LOG_CLOSE( )\n{close}\nEND\n"
    assert krl_violations(program(*opened, "IF x THEN", "LOG_CLOSE( )", "HALT", "ENDIF", "LOG_CLOSE( )",
                                  sub=closer)) == []
    # a subprogram runs with the main program's file open
    assert rules(program(*opened, "S( )", close, sub="DEF S( )\nHALT\nEND\n")) == {"file": [10]}


@pytest.mark.parametrize("on, ok", [("RSI_ON(#ABSOLUTE, #IPO)", True), ("RSI_ON(#ABSOLUTE, #IPO_FAST)", False),
                                    ("RSI_ON(#RELATIVE)", False)])
def test_programmed_motions_under_rsi_need_ipo(on, ok):
    text = program(f"ret = {on}", "LIN p1", "ret = RSI_OFF()", "LIN p2")
    assert (krl_violations(text) == []) is ok
    assert krl_violations(program(f"ret = {on}", "RSI_MOVECORR()", "ret = RSI_OFF()")) == []
