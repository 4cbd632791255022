"""Reading YAML: the one loader of every config, model and data file, without pydantic.

Kept apart from `stiffness.yamlio` (the schemas) so that a light command, such as the health probe,
reads a config without importing pydantic; `stiffness.yamlio` re-exports both names.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import yaml

from .errors import ConfigError


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
        mark = getattr(e, "problem_mark", None)
        where = f" line {mark.line + 1}" if mark is not None else ""
        raise ConfigError(f"{path}:{where} is not valid YAML: {getattr(e, 'problem', e)}") from e
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping at the top level, got {type(data).__name__}")
    return data
