"""Write one set of a service config's payload table (``gravity.payloads``): `stiffcomp payload --write-entry`.

The file is read with the one YAML loader, the entry added (or, with ``replace``, put in place of the
set with its index), and the whole config validated as the service validates it before the file is
replaced (in one rename, so a reader never sees half a file). Everything else in the file is kept as
data; its comments are not (PyYAML writes data only, and stiffcomp adds no round-trip YAML library
for this): `write_entry` says so in its message.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

from service.config import load_config
from service.errors import ServiceConfigError
from stiffness.errors import quote
from stiffness.yamlio import dump_yaml, read_yaml


def write_entry(config: str | Path, entry: dict, replace: bool = False) -> str:
    """Put ``entry`` (index, name, mass_kg, cog_mm, bias[, tcp_mm]) into ``config``'s ``gravity.payloads``;
    returns what was done, in words. ServiceConfigError (the file unchanged) when the index is taken and
    ``replace`` is False, or when the config with the entry does not validate (file, key, value)."""
    path = Path(config)
    data = read_yaml(path)          # ConfigError naming the file
    gravity = data.get("gravity") or {}
    if not isinstance(gravity, dict):
        raise ServiceConfigError(f"{path}: gravity = {quote(gravity)}: expected a mapping")
    table = list(gravity.get("payloads") or [])
    taken = [k for k, e in enumerate(table) if isinstance(e, dict) and e.get("index") == entry["index"]]
    if taken and not replace:
        old = table[taken[0]]
        raise ServiceConfigError(f"{path}: gravity.payloads already has index {entry['index']} "
                                 f"({quote(old.get('name'))}, {old.get('mass_kg')} kg); --replace overwrites it")
    if taken:
        table[taken[0]] = entry
    else:
        table.append(entry)
    data["gravity"] = {**gravity, "payloads": table}
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".yaml", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(dump_yaml(data, sort_keys=False, default_flow_style=None))
        try:
            load_config(tmp)
        except ServiceConfigError as e:
            raise ServiceConfigError(str(e).replace(tmp, str(path))) from e
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    verb = "replaced" if taken else "added"
    return (f"{path}: {verb} gravity.payloads set {entry['index']} {entry['name']!r} ({entry['mass_kg']:g} kg); "
            "note: the file was written from its data, so its comments are gone")
