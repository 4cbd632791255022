"""Reading YAML: the one loader of every config, model and data file, without pydantic.

Kept apart from `stiffness.files.yaml_schema` (the schemas) so that a light command, such as the health probe,
reads a config without importing pydantic; `stiffness.files.yaml_schema` re-exports both names.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from ..errors import ConfigError, quote


class NoAliasLoader(yaml.SafeLoader):
    """yaml.SafeLoader that refuses aliases (``*name``): nested aliases expand exponentially (a
    "billion laughs" file of a few hundred bytes takes minutes and gigabytes), and no config or model
    of ours needs them. An anchor alone (``&name``) is harmless and left alone."""

    def compose_node(self, parent, index):
        if self.check_event(yaml.AliasEvent):
            event = self.peek_event()
            raise yaml.MarkedYAMLError(
                problem=f"an alias (*{event.anchor}) is not accepted: write the value out in full "
                        "(aliases can expand without bound)",
                problem_mark=event.start_mark)
        return super().compose_node(parent, index)


def read_yaml(path: str | Path) -> dict[str, Any]:
    """Read a YAML mapping from ``path``; raise ConfigError naming the file on any failure."""
    path = Path(path)
    try:
        text = path.read_text()
    except OSError as e:
        raise ConfigError(f"{path}: cannot read: {e.strerror or e}") from e
    try:
        data = yaml.load(text, Loader=NoAliasLoader)
    except yaml.YAMLError as e:
        raise ConfigError(f"{path}: {syntax_error(e, text)}") from e
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of keys at the top level, but {kind_of(data)}")
    return data


# Where PyYAML notices a mistake is often the line after the one written: a key without its colon is
# noticed when the next line starts, an unclosed bracket or quote where the next key is. Its context
# mark then points at the line the user wrote. A key without its colon before a key of the same mapping
# reads as one plain scalar over both lines, and the next colon is "not allowed here": without a context
# mark, the line above (a line with no colon, not a list item or a comment) is the one written.
_CONTEXT_FIRST = ("while scanning a simple key", "while scanning a quoted scalar", "while parsing a flow")
_NOT_ALLOWED = "mapping values are not allowed here"


def syntax_error(e: yaml.YAMLError, text: str) -> str:
    """``line N ('the line') is not valid YAML: problem``, at the line the user wrote (see above)."""
    problem, context = getattr(e, "problem_mark", None), getattr(e, "context_mark", None)
    what = getattr(e, "problem", None) or str(e)
    if problem is None:
        return f"is not valid YAML: {what}"
    lines = text.splitlines()
    line = problem.line
    if context is not None and context.line < line and str(getattr(e, "context", "")).startswith(_CONTEXT_FIRST):
        line = context.line
        what += f" ({e.context} that starts here; noticed at line {problem.line + 1})"
    elif what == _NOT_ALLOWED and context is None:
        above = [k for k in range(min(line, len(lines))) if lines[k].strip() and not lines[k].lstrip().startswith("#")]
        written = lines[above[-1]].strip() if above else ""
        if written and ":" not in written and not written.startswith(("-", "[", "{")):
            line = above[-1]
            what = f"a key without its colon? ({what} at line {problem.line + 1})"
    written = lines[line].split(" #")[0].strip() if line < len(lines) else ""      # without its comment
    shown = f" ({quote(written)})" if written else ""
    return f"line {line + 1}{shown} is not valid YAML: {what}"


def kind_of(value: Any) -> str:
    """What a YAML value is, in words (never a Python type name)."""
    if value is None:
        return "the file is empty (or holds only comments)"
    if isinstance(value, list):
        return f"it holds a list of {len(value)} entries"
    return f"it holds a single value, {quote(value)}"
