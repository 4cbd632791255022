"""docs/config.md documents every key of the config schema, and nothing that is not in it.

The schema is service/config.py's pydantic models; the reference is one table per top-level section
(a heading ``## `section` ``) whose first column names keys in backticks, dotted below the section
(``ati.base_id``). A key is a leaf of the schema: a nested model is documented key by key.
"""

from __future__ import annotations

import re
import types
import typing
from pathlib import Path

from pydantic import BaseModel

from robot_road import registry
from robot_road.settings import RobotSettings
from service.config import ServiceConfig

DOC = Path(__file__).resolve().parents[2] / "docs" / "config.md"


def _model_of(annotation) -> type[BaseModel] | None:
    """The pydantic model in ``annotation`` (also inside ``X | None``), or None for a plain value."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        return annotation
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        models = [m for a in typing.get_args(annotation) if (m := _model_of(a))]
        return models[0] if models else None
    return None


def schema_keys(model: type[BaseModel] = ServiceConfig, prefix: str = "") -> set[str]:
    """Every leaf key of the schema, dotted from the top (``source.ati.base_id``); under ``robot`` also each built-in
    interface's sub-section, which its declaration's model validates (`robot_road.registry`)."""
    out = set()
    for name, field in model.model_fields.items():
        if field.exclude:
            continue
        sub = _model_of(field.annotation)
        out |= schema_keys(sub, f"{prefix}{name}.") if sub else {prefix + name}
    if model is RobotSettings:
        for name in registry.BUILT_IN:
            out |= schema_keys(registry.declared(name).settings, f"{prefix}{name}.")
    return out


def documented_keys(text: str) -> set[str]:
    """The keys named in the first column of the reference's tables, dotted under their section."""
    out, section = set(), None
    for line in text.splitlines():
        heading = re.match(r"^## `(\w+)`", line)
        if heading:
            section = heading.group(1)
        elif line.startswith("## "):
            section = None
        elif section and line.startswith("|") and not line.startswith("|---"):
            first = line.split("|")[1]
            out |= {f"{section}.{k}" for k in re.findall(r"`([a-z_][\w.]*)`", first)}
    return out


def test_every_schema_key_is_documented():
    missing = sorted(schema_keys() - documented_keys(DOC.read_text()))
    assert not missing, f"{DOC.name} lacks: {', '.join(missing)}"


def test_every_documented_key_exists():
    unknown = sorted(documented_keys(DOC.read_text()) - schema_keys())
    assert not unknown, f"{DOC.name} documents keys the schema does not have: {', '.join(unknown)}"


def test_the_check_sees_nested_and_optional_sections():
    keys = schema_keys()
    assert {"source.ati.base_id", "source.replay.file", "filter.spike.max_held", "gravity.tool.cog_mm",
            "monitoring.health_max_exceed_rate"} <= keys
    assert "source.replay" not in keys and "path" not in keys
    assert documented_keys("## `x`\n| key |\n|---|\n| `a`, `b.c` | 1 |\n## Other\n| `d` |\n") == {"x.a", "x.b.c"}
