"""What a writer says when a program breaks its controller language's rule: the rule, the file and the line."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from stiffness.errors import StiffnessError


@dataclass(frozen=True)
class Violation:
    """One broken rule: its short name, the 1-based line, the line's text and what the maker's manual says."""

    rule: str
    line: int
    text: str
    why: str

    def __str__(self) -> str:
        return f"line {self.line}: {self.rule}: {self.why}: {self.text.strip()}"


class ProgramRuleError(StiffnessError):
    """A writer refused to write a program that breaks a rule of its controller's language."""

    def __init__(self, name: str, violations: list[Violation]):
        self.name, self.violations = name, list(violations)
        lines = "; ".join(str(v) for v in violations[:5])
        more = f" (and {len(violations) - 5} more)" if len(violations) > 5 else ""
        super().__init__(f"{name}: refused, {len(violations)} rule(s) broken: {lines}{more}")


def refuse_broken(name: str, text: str, violations: list[Violation]) -> str:
    """``text`` when no rule is broken; ProgramRuleError naming every broken rule otherwise."""
    if violations:
        raise ProgramRuleError(name, violations)
    return text


class ProgramWriter:
    """Collects a program's lines; ``render`` gives its text, or ProgramRuleError naming each rule ``check`` (the
    language's checker: text -> violations) finds broken."""

    def __init__(self, name: str, check: Callable[[str], list[Violation]]):
        self.name, self.lines, self.check = name, [], check

    def add(self, *lines: str) -> ProgramWriter:
        for block in lines:
            self.lines.extend(block.split("\n"))
        return self

    def render(self) -> str:
        text = "\n".join(self.lines) + "\n"
        return refuse_broken(self.name, text, self.check(text))
