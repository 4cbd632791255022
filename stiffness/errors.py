"""The model core's exception tree.

StiffnessError
├── ConfigError       a robot or model YAML is malformed: names the file, key, value and allowed range
├── DataError         a measurement file is malformed: names the file, line and column
└── OutputError       a result cannot be written where it was asked to go
"""

from __future__ import annotations

import reprlib

_QUOTE = reprlib.Repr()
_QUOTE.maxstring = _QUOTE.maxother = 60
_QUOTE.maxlist = _QUOTE.maxtuple = 6
_QUOTE.maxdict, _QUOTE.maxlevel = 4, 2


def quote(value: object) -> str:
    """``repr(value)`` cut to at most ~80 characters, for quoting a user's value in an error message
    (a value may be a long string, or a deep structure a file built)."""
    text = _QUOTE.repr(value)
    return text if len(text) <= 80 else text[:77] + "..."


class StiffnessError(Exception):
    """Base of every error the model core raises on bad input."""


class ConfigError(StiffnessError):
    """Raised when a robot or model YAML file is missing, unreadable or holds an invalid value."""


class DataError(StiffnessError):
    """Raised when a measurement file is missing, unreadable or holds invalid rows.

    ``problems`` lists the bad rows found (the first `Problems.LIMIT` of them), each a human-readable
    line; ``count`` is how many were found in all.
    """

    def __init__(self, message: str, problems: list[str] | Problems | None = None):
        if isinstance(problems, Problems):
            self.problems, self.count = list(problems.kept), problems.count
        else:
            self.problems = list(problems or [])
            self.count = len(self.problems)
        if self.problems:
            shown = self.problems[:20]
            more = self.count - len(shown)
            message += "\n  " + "\n  ".join(shown)
            if more:
                message += f"\n  ... and {more} more"
        super().__init__(message)


class Problems:
    """A list of problems that keeps the first LIMIT and counts the rest, so a file of garbage costs
    memory for its rows, not for its (many more) problems."""

    LIMIT = 1000

    def __init__(self) -> None:
        self.kept: list[str] = []
        self.count = 0

    def add(self, text: str | None) -> None:
        """Count a problem; keep its text while below LIMIT. None counts it only: a caller in a hot
        loop passes None once `full`, and composes no text nobody reads."""
        self.count += 1
        if text is not None and len(self.kept) < self.LIMIT:
            self.kept.append(text)

    @property
    def full(self) -> bool:
        """True once LIMIT problems are kept: a caller may skip composing the text of the next."""
        return len(self.kept) >= self.LIMIT

    def __bool__(self) -> bool:
        return self.count > 0

    def __len__(self) -> int:
        return self.count


class OutputError(StiffnessError):
    """Raised when an output file or report folder cannot be written (names the path and the reason)."""
