"""What kind of the project's YAML files a mapping looks like, by its top-level keys: so that a file passed
where another kind belongs (the register map as ``--config``) is refused naming what it is, instead of
"word_order is not a known key" alone.

Standard library only: the health probe calls it, and a probe imports little.
"""

from __future__ import annotations

from collections.abc import Collection, Mapping
from dataclasses import dataclass


@dataclass(frozen=True)
class Kind:
    """One kind of file: its name, the top-level keys only it has, its format's doc and where it belongs."""

    name: str
    keys: tuple[str, ...]
    doc: str
    belongs: str


# only the keys that tell the kind apart: not name or description, which several kinds share
KINDS = (
    Kind("a register map", ("word_order", "to_plc", "from_plc"), "docs/register_map.md",
         "a service config names it in plc.register_map"),
    Kind("a stiffness model", ("effects", "noise"), "docs/model_format.md",
         "a service config names it in model.file"),
    Kind("a robot file", ("dh", "urdf", "joint_limits_deg", "inertial", "extends", "tcp"), "docs/robot_format.md",
         "a stiffness model names it in robot"),
    Kind("a HIL scenario", ("truth", "circle", "milling", "cmm", "payload", "service", "sensor"), "docs/hil.md",
         "stiffcomp hil circle takes it as --scenario"),
)


def looks_like(data: Mapping, expected: Collection[str]) -> str | None:
    """What ``data`` (a file's top-level mapping) looks like when it is not the kind whose top-level keys are
    ``expected``, in words with its evidence, e.g. "a register map (its keys word_order, to_plc, from_plc;
    docs/register_map.md): a service config names it in plc.register_map"; None when no other kind has more
    of its keys than the expected kind has."""
    keys = [k for k in data if isinstance(k, str)]
    ours = sum(k in expected for k in keys)
    best, hits = None, []
    for kind in KINDS:
        found = [k for k in keys if k in kind.keys and k not in expected]
        if len(found) > max(ours, len(hits)):
            best, hits = kind, found
    if best is None:
        return None
    return f"{best.name} (its keys {', '.join(hits)}; {best.doc}): {best.belongs}"
