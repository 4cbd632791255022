"""ABB RAPID: the rules of the language an IRC5 or OmniCore (RobotWare 6, 7) runs, checked on a module's text, and the
writer that refuses a module breaking one.

The rules, with the maker's word (ABB, *Technical reference manual - RAPID Instructions, Functions and Data types*,
3HAC050917-001, "RAPID reference"; *Technical reference manual - RAPID kernel*, 3HAC050946-001, "RAPID kernel"):

``string``      a ``string`` holds at most 80 characters (RAPID reference, data type string: "a string can have
                0 to 80 characters"); a concatenation that would be longer raises ERR_STRTOOLNG and stops the
                program. Every ``+`` chain of literals, string CONSTs and ``NumToStr(value, dec)`` is measured at its
                longest: NumToStr writes the value rounded to ``dec`` decimals (RAPID reference, NumToStr), so its
                widest text is a sign, the integer digits of the largest value the expression can take (``bounds``;
                by default 5 digits, a cell's millimetres), the point and ``dec`` decimals. ``Write``'s string and
                its ``\\Num`` value (at most 12 characters) are measured together. Where a line is longer, write it
                in pieces with ``Write .. \\NoNewLine`` (RAPID reference, Write: \\NoNewLine omits the line feed).
``identifier``  an identifier has at most 32 characters (RAPID kernel, "Identifiers").
``handler``     a routine that opens a file needs an ERROR handler that closes it on every error, before any test
                of ERRNO, and ends the program there (``EXIT``): an error the handler does not take goes up to the
                caller and the program stops with the file open (RAPID kernel, "Error recovery"). SearchL raises
                ERR_WHLSEARCH (no hit) and ERR_SIGSUPSEARCH (the signal already high at the start) (RAPID reference,
                SearchL), the string and file instructions their own (ERR_STRTOOLNG, ERR_FILEACC, ...): one handler
                takes them all.
"""

from __future__ import annotations

import math
import re

from .rules import ProgramWriter, Violation

MAX_STRING = 80
MAX_IDENTIFIER = 32
DEFAULT_DIGITS = 5
WRITE_NUM_WIDTH = 12
_LITERAL = r'"[^"]*"'
_NUMTOSTR = r"NumToStr\s*\(\s*([^,()]+(?:\([^()]*\))?)\s*,\s*(\d+)\s*\)"
_TERM = re.compile(rf"({_LITERAL}|{_NUMTOSTR}|[A-Za-z_][\w.]*)")
_KEYWORDS = {"MODULE", "ENDMODULE", "PROC", "ENDPROC", "FUNC", "ENDFUNC", "TRAP", "ENDTRAP", "CONST", "PERS", "VAR"}

WHY = {
    "string": f"a RAPID string holds at most {MAX_STRING} characters; a longer concatenation raises ERR_STRTOOLNG "
              "(RAPID reference, string; NumToStr)",
    "identifier": f"a RAPID identifier has at most {MAX_IDENTIFIER} characters (RAPID kernel, Identifiers)",
    "handler": "a routine that opens a file must close it in its ERROR handler on every error, before testing "
               "ERRNO, and EXIT there (RAPID kernel, Error recovery)",
}


def code_of(line: str) -> str:
    """A RAPID line without its comment (``!`` outside a string)."""
    return re.sub(r'^((?:[^"!]|"[^"]*")*)!.*$', r"\1", line)


def _statements(lines: list[str]) -> list[tuple[int, str]]:
    """Each statement (to its ``;``, over continued lines) with the number of its first line."""
    out, start, parts = [], 0, []
    for n, raw in enumerate(lines, 1):
        code = code_of(raw).strip()
        if not code:
            continue
        if not parts:
            start = n
        parts.append(code)
        if code.endswith(";") or code.split()[0].upper() in _KEYWORDS - {"CONST", "PERS", "VAR"} or \
                code.upper() in ("ERROR", "ENDIF", "ENDFOR", "ENDWHILE", "ELSE"):
            out.append((start, " ".join(parts)))
            parts = []
    return out


def numtostr_width(expr: str, decimals: int, bounds: dict[str, float]) -> int:
    """The widest text ``NumToStr(expr, decimals)`` can give: sign, integer digits, point and decimals."""
    bound = next((b for pattern, b in bounds.items() if re.fullmatch(pattern, expr.strip())), None)
    digits = DEFAULT_DIGITS if bound is None else max(1, len(str(math.floor(abs(bound)))))
    return 1 + digits + (1 + decimals if decimals > 0 else 0)


def longest(expr: str, consts: dict[str, str], bounds: dict[str, float]) -> int | None:
    """The longest string a ``+`` chain of literals, string CONSTs and NumToStr calls builds; None when ``expr``
    is not such a chain (a number, a name of another type)."""
    terms = [t.strip() for t in _split_plus(expr)]
    sizes = []
    for term in terms:
        m = re.fullmatch(_NUMTOSTR, term)
        if term.startswith('"') and term.endswith('"'):
            sizes.append(len(term) - 2)
        elif m:
            sizes.append(numtostr_width(m.group(1), int(m.group(2)), bounds))
        elif term in consts:
            sizes.append(len(consts[term]))
        else:
            sizes.append(None)
    if all(s is None for s in sizes):
        return None
    return sum(MAX_STRING + 1 if s is None else s for s in sizes)


def _split_plus(expr: str) -> list[str]:
    out, depth, quoted, cur = [], 0, False, []
    for ch in expr:
        if ch == '"':
            quoted = not quoted
        elif not quoted and ch in "([":
            depth += 1
        elif not quoted and ch in ")]":
            depth -= 1
        if ch == "+" and depth == 0 and not quoted:
            out.append("".join(cur))
            cur = []
        else:
            cur.append(ch)
    return out + ["".join(cur)]


def _string_violations(stmts: list[tuple[int, str]], lines: list[str], bounds: dict[str, float]) -> list[Violation]:
    consts = {m.group(1): m.group(2) for _, s in stmts
              for m in [re.match(r'CONST\s+string\s+(\w+)\s*:=\s*"([^"]*)"\s*;', s)] if m}
    out = []
    for n, s in stmts:
        write = re.match(r"(?:Write\s+\w+|TPWrite|ErrWrite[^,]*)\s*,?\s*(.*?)\s*((?:\\\w+(?::=[^\\;]*)?\s*)*);$", s)
        assign = re.match(r"[\w.]+\s*:=\s*(.*);$", s)
        expr = (write or assign).group(1) if (write or assign) else None
        if expr is None or not expr:
            continue
        size = longest(expr, consts, bounds)
        if size is not None and write and "\\Num" in write.group(2):
            size += WRITE_NUM_WIDTH
        if size is not None and size > MAX_STRING:
            out.append(Violation("string", n, lines[n - 1], f"up to {size} characters; " + WHY["string"]))
    return out


def _handler_violations(stmts: list[tuple[int, str]], lines: list[str]) -> list[Violation]:
    out, proc, opens, section = [], None, False, None
    for n, s in stmts:
        head = s.split()[0].upper()
        if head in ("PROC", "FUNC", "TRAP"):
            proc, opens, section = (n, s), False, None
        elif re.match(r"Open\b", s):
            opens = True
        elif s.upper() == "ERROR":
            section = []
        elif head in ("ENDPROC", "ENDFUNC", "ENDTRAP") and proc is not None:
            if opens and not _good_handler(section):
                out.append(Violation("handler", proc[0], lines[proc[0] - 1], WHY["handler"]))
            proc = None
        elif section is not None:
            section.append(s)
    return out


def _good_handler(section: list[str] | None) -> bool:
    """The handler closes the file and EXITs before any IF or TEST."""
    closed = False
    for s in section or []:
        if re.match(r"(IF|TEST)\b", s):
            return False
        closed = closed or bool(re.match(r"Close\b", s))
        if re.match(r"EXIT\s*;", s):
            return closed
    return False


def rapid_violations(text: str, bounds: dict[str, float] | None = None) -> list[Violation]:
    """Every rule of the module docstring ``text`` breaks, in line order. ``bounds``: the largest absolute value
    of the expressions NumToStr is given (a regular expression of the expression's text: its bound)."""
    lines = text.splitlines()
    stmts = _statements(lines)
    out = _string_violations(stmts, lines, bounds or {}) + _handler_violations(stmts, lines)
    for n, raw in enumerate(lines, 1):
        for name in re.findall(r"(?<![\w.\"])[A-Za-z_]\w*", re.sub(_LITERAL, '""', code_of(raw))):
            if len(name) > MAX_IDENTIFIER:
                out.append(Violation("identifier", n, raw, f"{name} has {len(name)} characters; " + WHY["identifier"]))
    return sorted(out, key=lambda v: v.line)


class RapidWriter(ProgramWriter):
    """Collects a RAPID module's lines; ``render`` gives its text, or ProgramRuleError naming each rule it breaks.
    ``bounds`` as rapid_violations takes them."""

    def __init__(self, name: str, bounds: dict[str, float] | None = None):
        super().__init__(name, lambda text: rapid_violations(text, dict(bounds or {})))


def rapid_num(value: float) -> str:
    """A num literal as RAPID writes it, to 6 decimals (a micrometre, a microdegree): ``250``, ``-0.5``, ``1.25``."""
    if not math.isfinite(value) or abs(value) >= 1e9:
        raise ValueError(f"{value!r} has no plain RAPID num literal")
    text = f"{round(float(value), 6):.6f}".rstrip("0").rstrip(".")
    return "0" if text in ("-0", "") else text
