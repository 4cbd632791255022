"""The model core's exception tree.

StiffnessError
├── ConfigError       a robot or model YAML is malformed: names the file, key, value and allowed range
├── DataError         a measurement file is malformed: names the file, line and column
└── OutputError       a result cannot be written where it was asked to go
"""


class StiffnessError(Exception):
    """Base of every error the model core raises on bad input."""


class ConfigError(StiffnessError):
    """Raised when a robot or model YAML file is missing, unreadable or holds an invalid value."""


class DataError(StiffnessError):
    """Raised when a measurement file is missing, unreadable or holds invalid rows.

    ``problems`` lists every bad row found (not only the first), each a human-readable line.
    """

    def __init__(self, message: str, problems: list[str] | None = None):
        self.problems = list(problems or [])
        if self.problems:
            shown = self.problems[:20]
            more = len(self.problems) - len(shown)
            message += "\n  " + "\n  ".join(shown)
            if more:
                message += f"\n  ... and {more} more"
        super().__init__(message)


class OutputError(StiffnessError):
    """Raised when an output file or report folder cannot be written (names the path and the reason)."""
