"""Loading YAML with pydantic validation and errors that name the file, key, value and allowed range."""

from __future__ import annotations

from pathlib import Path
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from .errors import ConfigError, quote

M = TypeVar("M", bound=BaseModel)


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


class Strict(BaseModel):
    """The base of every YAML schema: unknown keys are refused (a typo must not fall back to a default),
    and so are inf and NaN (an infinite limit would silently disable it)."""

    model_config = ConfigDict(extra="forbid", allow_inf_nan=False)


class _NoAliasDumper(yaml.SafeDumper):
    """yaml.SafeDumper that writes a value shared twice in full twice, never as an alias."""

    def ignore_aliases(self, data: Any) -> bool:
        return True


class FlowList(list):
    """A list `dump_yaml` writes on one line (``[a, b, c]``): a matrix's row."""


_NoAliasDumper.add_representer(
    FlowList, lambda dumper, data: dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=True))


def dump_yaml(data: Any, **options: Any) -> str:
    """YAML text of ``data`` without aliases (`read_yaml` refuses them), the one way stiffcomp writes
    YAML a person or stiffcomp reads again; ``options`` as for ``yaml.safe_dump``."""
    return yaml.dump(data, Dumper=_NoAliasDumper, **options)


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


def format_validation_error(source: str, err: ValidationError, prefix: str = "") -> str:
    """One line per problem: ``source: key.path = value: reason``."""
    lines = []
    for e in err.errors():
        key = ".".join(str(p) for p in (prefix.split(".") if prefix else []) + list(e["loc"]))
        if e["type"] == "extra_forbidden":
            lines.append(f"{source}: {key} is not a known key")
        elif e["type"] == "missing":
            lines.append(f"{source}: {key} is missing")
        else:
            lines.append(f"{source}: {key} = {quote(e.get('input'))}: {e['msg']}")
    return "\n".join(lines)


def validate(model: type[M], data: dict[str, Any], source: str, prefix: str = "") -> M:
    """Validate ``data`` against a pydantic model, raising ConfigError with readable lines."""
    try:
        return model.model_validate(data)
    except ValidationError as e:
        raise ConfigError(format_validation_error(source, e, prefix)) from e


def deep_update(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """Merge ``over`` into ``base`` at every depth (a nested mapping is merged, anything else replaced);
    the one way configs are overridden (tests, HIL runs, benchmarks). Returns ``base``."""
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(base.get(k), dict):
            deep_update(base[k], v)
        else:
            base[k] = v
    return base
