"""Loading YAML with pydantic validation and errors that name the file, key, value and allowed range."""

from __future__ import annotations

import types
import typing
from typing import Any, TypeVar

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from ..errors import ConfigError, quote
from .yaml_syntax import NoAliasLoader, kind_of, read_yaml, syntax_error  # noqa: F401 - re-exported: reading lives in yaml_syntax

M = TypeVar("M", bound=BaseModel)


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


def items_by_key(key: str) -> dict[str, Any]:
    """For a list field's ``json_schema_extra``: error messages name its entries by that key's value,
    ``payloads[index 3]`` (by number from 1, ``[entry 2]``, where an entry lacks it)."""
    return {"items_key": key}


def items_numbered(noun: str) -> dict[str, Any]:
    """For a list field's ``json_schema_extra``: error messages name its entries by number from 1, with
    ``noun``: ``links[link 2]`` (not pydantic's 0-based position)."""
    return {"items_noun": noun}


def format_validation_error(source: str, err: ValidationError, prefix: str = "",
                            schema: type[BaseModel] | None = None, data: Any = None) -> str:
    """One line per problem: ``source: key.path = value: reason``. With the ``schema`` and the ``data``
    validated, a list's entries are named as the schema says (`items_by_key`, `items_numbered`), not by
    0-based position;
    a list or mapping value is described, never dumped."""
    lines = []
    for e in err.errors():
        key = _key_path(list(e["loc"]), schema, data)
        key = f"{prefix}.{key}" if prefix and key else prefix or key
        if e["type"] == "extra_forbidden":
            lines.append(f"{source}: {key} is not a known key")
        elif e["type"] == "missing":
            lines.append(f"{source}: {key} is missing")
        else:
            value = e.get("input")
            shown = (f" has {len(value)} entries" if isinstance(value, list) and any(
                isinstance(v, (dict, list)) for v in value) else
                f" (a mapping of {', '.join(map(str, value))})" if isinstance(value, dict) else f" = {quote(value)}")
            lines.append(f"{source}: {key}{shown}: {e['msg'].removeprefix('Value error, ')}")
    return "\n".join(lines)


def _key_path(loc: list, schema: type[BaseModel] | None, data: Any) -> str:
    """The dotted key of a pydantic error location, a list's entries named as its schema says
    (`items_by_key`, `items_numbered`); other positions stay as pydantic gives them."""
    out, naming = "", {}
    for part in loc:
        if isinstance(part, int) and naming:
            entry = _step(data, part)
            key = naming.get("items_key")
            if key is not None and isinstance(entry, dict) and key in entry:
                out += f"[{key} {entry[key]}]"
            else:
                out += f"[{naming.get('items_noun', 'entry')} {part + 1}]"
        else:
            out += f".{part}" if out else str(part)
        naming = {}
        field = schema.model_fields.get(part) if isinstance(part, str) and schema is not None else None
        if field is not None:
            extra = field.json_schema_extra
            naming = extra if isinstance(extra, dict) else {}
            schema = _schema_in(field.annotation)
        elif not isinstance(part, int):
            schema = None
        data = _step(data, part)
    return out


def _step(data: Any, part: Any) -> Any:
    if isinstance(data, dict):
        return data.get(part)
    if isinstance(data, list) and isinstance(part, int) and part < len(data):
        return data[part]
    return None


def _schema_in(annotation: Any) -> type[BaseModel] | None:
    """The pydantic model inside a field's type (``list[X] | None`` -> X), or None."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    if typing.get_origin(annotation) in (typing.Union, types.UnionType, list, tuple, typing.Annotated):
        for arg in typing.get_args(annotation):
            found = _schema_in(arg)
            if found is not None:
                return found
    return None


def validate(model: type[M], data: dict[str, Any], source: str, prefix: str = "") -> M:
    """Validate ``data`` against a pydantic model, raising ConfigError with readable lines."""
    try:
        return model.model_validate(data)
    except ValidationError as e:
        raise ConfigError(format_validation_error(source, e, prefix, model, data)) from e


def deep_update(base: dict[str, Any], over: dict[str, Any]) -> dict[str, Any]:
    """Merge ``over`` into ``base`` at every depth (a nested mapping is merged, anything else replaced);
    the one way configs are overridden (tests, HIL runs, benchmarks). Returns ``base``."""
    for k, v in over.items():
        if isinstance(v, dict) and isinstance(base.get(k), dict):
            deep_update(base[k], v)
        else:
            base[k] = v
    return base
