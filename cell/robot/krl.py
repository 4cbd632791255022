"""KUKA KRL: the rules of the language a KR C4 (KSS 8.x) runs, checked on a program's text, and the writer that
refuses a program breaking one.

The rules, with the maker's word (KUKA System Software 8.x, *Operating and Programming Instructions for System
Integrators*, KSS 8.x SI; and *CREAD/CWRITE, Programming CREAD/CWRITE and Related Statements, for KUKA System
Software 8.2, 8.3*, CREAD/CWRITE manual):

``name``        a name in KRL has at most 24 characters (KSS 8.x SI, "Names in KRL").
``declaration`` declarations stand in a DEF's declaration section, before its first statement (KSS 8.x SI,
                "Structure of a KRL program": the declaration section precedes the instruction section; a DECL
                after a statement does not compile). ``INTERRUPT DECL`` is a statement and may stand anywhere.
``escape``      a KRL string literal has no escape sequences: ``"a\\n"`` is the characters a, backslash, n. The
                format strings of CWRITE/SWRITE know only ``%`` conversions (CREAD/CWRITE manual, "Format
                specification"); a line ends by writing it with ``krl_fwriteln`` (CREAD/CWRITE manual, "$FCT_CALL:
                krl_fwriteln": writes the string and ends the line), not by a ``\\n`` in a literal.
``advance``     the advance run reads statements ahead of the motion (KSS 8.x SI, "Advance run"): an
                ``INTERRUPT ON`` or an assignment after a motion runs while the robot is still on that motion,
                unless the advance run is stopped between them, by ``WAIT SEC 0`` (or ``WAIT FOR``, ``HALT``) or a
                change of ``$ADVANCE`` (KSS 8.x SI, "Advance run stop"). A subprogram is entered with the motion
                before its call still running, so its first ``INTERRUPT ON`` needs a stop too.
``file``        a file opened with ``krl_fopen`` stays open until ``krl_fclose`` (CREAD/CWRITE manual, "$FCT_CALL:
                krl_fopen", "krl_fclose"); HALT does not close it, and a program stopped at a HALT with its log open
                leaves the log unflushed. Every HALT and RETURN while the file is open must come right after its
                close (a ``krl_fclose`` or a call of a subprogram that closes it), and the program must not END with it
                open.
``rsi``         KUKA.RobotSensorInterface (KST RSI 3.3, "RSI_ON", sensor mode; RSI 4.x the same): with sensor mode
                ``#IPO_FAST`` (4 ms, the default when RSI_ON has one argument) the correction acts only in sensor-guided
                motion, ``RSI_MOVECORR()``; a correction laid over programmed LIN/CIRC/PTP motions (path correction)
                needs ``#IPO`` (12 ms). A programmed motion between ``RSI_ON(.., #IPO_FAST)`` and ``RSI_OFF`` is refused.
                The modes' cycles are KST RSI 3.3's section 7.1.4 as a setup guide quotes it; the sentence that
                keeps #IPO_FAST for RSI_MOVECORR was not readable here (docs/robot.md, "Which sensor mode").
"""

from __future__ import annotations

import math
import re

from .rules import ProgramWriter, Violation

MAX_NAME = 24
_STRING = re.compile(r'"[^"]*"')
_NAME = re.compile(r"(?<![$#&\w])[A-Za-z_]\w*")
_DEF = re.compile(r"^(?:GLOBAL\s+)?DEF(?:FCT\s+\w+)?\s+(\w+)\s*\(", re.IGNORECASE)
_END = re.compile(r"^END(?:FCT)?\b", re.IGNORECASE)
_DECL = re.compile(r"^(?:DECL\b|(?:GLOBAL\s+)?(?:INT|REAL|BOOL|CHAR|FRAME|POS|E6POS|AXIS|E6AXIS|STATE_T|MODUS_T)"
                   r"\s+[A-Za-z_])", re.IGNORECASE)
_MOTION = re.compile(r"^(?:PTP|LIN|CIRC|SPTP|SLIN|SCIRC|PTP_REL|LIN_REL|CIRC_REL|SPL)\b", re.IGNORECASE)
_STOP = re.compile(r"^(?:WAIT\s+(?:SEC|FOR)\b|HALT\b|\$ADVANCE\s*=)", re.IGNORECASE)
_INTERRUPT_ON = re.compile(r"^INTERRUPT\s+ON\b", re.IGNORECASE)
_ESCAPE = re.compile(r"\\[nrt0\\'\"]")
_RSI_ON = re.compile(r"RSI_ON\s*\(\s*#\w+\s*(?:,\s*#(\w+)\s*)?\)", re.IGNORECASE)
_HALT = re.compile(r"^(?:HALT|RETURN)\b", re.IGNORECASE)

WHY = {
    "name": f"a KRL name has at most {MAX_NAME} characters (KSS 8.x SI, 'Names in KRL')",
    "declaration": "a declaration after a statement (KSS 8.x SI: the declaration section precedes the statements)",
    "escape": "KRL strings have no escape sequences; end a line with krl_fwriteln (CREAD/CWRITE manual)",
    "advance": "INTERRUPT ON runs in the advance run while the last motion still moves: stop the advance run "
               "first (WAIT SEC 0 or $ADVANCE, KSS 8.x SI 'Advance run stop')",
    "rsi": "a programmed motion under RSI_ON(.., #IPO_FAST): KUKA.RSI corrects programmed motions only in #IPO "
           "(12 ms); #IPO_FAST acts only in RSI_MOVECORR (KST RSI 3.3, RSI_ON)",
    "file": "HALT, RETURN or END with the krl_fopen file still open (CREAD/CWRITE manual: open until krl_fclose)",
}


def code_of(line: str) -> str:
    """A KRL line without its comment (``;`` outside a string) and its surrounding blanks."""
    out, quoted = [], False
    for ch in line:
        if ch == '"':
            quoted = not quoted
        elif ch == ";" and not quoted:
            break
        out.append(ch)
    return "".join(out).strip()


def _blocks(lines: list[str]) -> list[tuple[str, list[tuple[int, str]]]]:
    """Each DEF (or DEFFCT) of a .src file: its name and its code lines (1-based number, code), DEF to END."""
    blocks, current = [], None
    for n, raw in enumerate(lines, 1):
        code = code_of(raw)
        if not code or code.startswith("&"):
            continue
        head = _DEF.match(code)
        if head and current is None:
            current = (head.group(1), [(n, code)])
        elif current is not None:
            current[1].append((n, code))
            if _END.match(code):
                blocks.append(current)
                current = None
    return blocks


def _names_and_escapes(lines: list[str]) -> list[Violation]:
    out = []
    for n, raw in enumerate(lines, 1):
        code = code_of(raw)
        if not code or code.startswith("&"):
            continue
        for literal in _STRING.findall(code):
            if _ESCAPE.search(literal):
                out.append(Violation("escape", n, raw, WHY["escape"]))
        for name in _NAME.findall(_STRING.sub('""', code)):
            if len(name) > MAX_NAME:
                out.append(Violation("name", n, raw, f"{name} has {len(name)} characters; " + WHY["name"]))
    return out


def _declarations(body: list[tuple[int, str]], lines: list[str]) -> list[Violation]:
    out, started = [], False
    for n, code in body[1:]:
        if _DECL.match(code):
            if started:
                out.append(Violation("declaration", n, lines[n - 1], WHY["declaration"]))
        else:
            started = True
    return out


def _advance(body: list[tuple[int, str]], lines: list[str], main: bool) -> list[Violation]:
    out, moving = [], not main
    for n, code in body[1:]:
        if _MOTION.match(code):
            moving = True
        elif _STOP.match(code):
            moving = False
        elif _INTERRUPT_ON.match(code) and moving:
            out.append(Violation("advance", n, lines[n - 1], WHY["advance"]))
    return out


def _rsi(body: list[tuple[int, str]], lines: list[str]) -> list[Violation]:
    out, fast = [], False
    for n, code in body[1:]:
        on = _RSI_ON.search(code)
        if on:
            fast = (on.group(1) or "IPO_FAST").upper() == "IPO_FAST"
        elif re.search(r"\bRSI_OFF\s*\(", code, re.IGNORECASE):
            fast = False
        elif fast and _MOTION.match(code):
            out.append(Violation("rsi", n, lines[n - 1], WHY["rsi"]))
    return out


def _closes(code: str, closers: set[str]) -> bool:
    call = re.match(r"^(\w+)\s*\(", code)
    return "krl_fclose" in code or (call is not None and call.group(1).upper() in closers)


def _files(body: list[tuple[int, str]], lines: list[str], state: str, closers: set[str],
           main: bool) -> list[Violation]:
    """HALT, RETURN or END while the log is open, not right after its close. ``state``: closed or open on entry;
    after krl_fopen it is opening (the IF that tests the open's result may HALT) until its ENDIF or the next
    statement. A subprogram's END returns to its caller, which holds the file; the main program's ends it."""
    out, last = [], ""
    for n, code in body[1:]:
        if "krl_fopen" in code:
            state = "opening"
        elif _closes(code, closers):
            state = "closed"
        elif state == "opening" and not (code.upper().startswith("IF") or _HALT.match(code)):
            state = "open"
        elif (_HALT.match(code) or (main and _END.match(code))) and state == "open" and not _closes(last, closers):
            out.append(Violation("file", n, lines[n - 1], WHY["file"]))
        last = code
    return out


def krl_violations(text: str) -> list[Violation]:
    """Every rule of the module docstring ``text`` (a .src or .dat file) breaks, in line order."""
    lines = text.splitlines()
    out = _names_and_escapes(lines)
    blocks = _blocks(lines)
    opens = any("krl_fopen" in code for _, body in blocks for _, code in body)
    closers = {name.upper() for name, body in blocks[1:] if any("krl_fclose" in c for _, c in body)}
    for i, (name, body) in enumerate(blocks):
        out += _declarations(body, lines) + _advance(body, lines, main=i == 0) + _rsi(body, lines)
        if opens and name.upper() not in closers:
            own = i == 0 or any("krl_fopen" in c for _, c in body)
            out += _files(body, lines, "closed" if own else "open", closers, main=i == 0)
    return sorted(out, key=lambda v: v.line)


class KrlWriter(ProgramWriter):
    """Collects a KRL file's lines; ``render`` gives its text, or ProgramRuleError naming each rule it breaks."""

    def __init__(self, name: str):
        super().__init__(name, krl_violations)


def krl_real(value: float) -> str:
    """A REAL literal as KRL writes it, to 6 decimals and always with a decimal point (``250.0``, ``-0.5``)."""
    if not math.isfinite(value) or abs(value) >= 1e9:
        raise ValueError(f"{value!r} has no plain KRL REAL literal")
    text = f"{round(float(value), 6):.6f}".rstrip("0")
    text = text + "0" if text.endswith(".") else text
    return "0.0" if text == "-0.0" else text
