"""Write one set of a service config's payload table (``gravity.payloads``): `stiffcomp payload --write-entry`.

The file is read with the one YAML loader (its checks: aliases refused, errors naming the line), then
edited in ruamel.yaml's round trip, which keeps every comment, the key order and the number formats
(``base_id: 0x020`` stays hex): the entry is added (or, with ``replace``, its values put in place of the
set with its index, whose comments stay). The whole config with the entry is validated as the service
validates it before the file is replaced (in one rename, so a reader never sees half a file).
"""

from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

from ruamel.yaml import YAML
from ruamel.yaml.comments import CommentedMap, CommentedSeq
from ruamel.yaml.tokens import CommentToken

from service.config import load_config
from service.errors import ServiceConfigError
from stiffness.errors import quote
from stiffness.files.yaml_schema import read_yaml


def write_entry(config: str | Path, entry: dict, replace: bool = False) -> str:
    """Put ``entry`` (index, name, mass_kg, cog_mm, bias[, tcp_mm]) into ``config``'s ``gravity.payloads``;
    returns what was done, in words. ServiceConfigError (the file unchanged) when the index is taken and
    ``replace`` is False, or when the config with the entry does not validate (file, key, value)."""
    path = Path(config)
    data = read_yaml(path)          # ConfigError naming the file (and the line)
    gravity = data.get("gravity") or {}
    if not isinstance(gravity, dict):
        raise ServiceConfigError(f"{path}: gravity = {quote(gravity)}: expected a mapping")
    if not isinstance(gravity.get("payloads") or [], list):
        raise ServiceConfigError(f"{path}: gravity.payloads: expected a list of payload sets")
    table = list(gravity.get("payloads") or [])
    taken = [k for k, e in enumerate(table) if isinstance(e, dict) and e.get("index") == entry["index"]]
    if taken and not replace:
        old = table[taken[0]]
        raise ServiceConfigError(f"{path}: gravity.payloads already has index {entry['index']} "
                                 f"({quote(old.get('name'))}, {old.get('mass_kg')} kg); --replace overwrites it")
    yaml = _round_trip()
    doc = yaml.load(path.read_text())
    _put(doc, entry, taken[0] if taken else None)
    text = io.StringIO()
    yaml.dump(doc, text)
    _replace_checked(path, text.getvalue())
    verb = "replaced" if taken else "added"
    return (f"{path}: {verb} gravity.payloads set {entry['index']} {entry['name']!r} ({entry['mass_kg']:g} kg); "
            "the rest of the file, its comments included, is as it was")


def _round_trip() -> YAML:
    """ruamel.yaml's round trip, writing null as ``null`` (its default writes nothing) and long lines whole."""
    yaml = YAML()
    yaml.width = 4096
    yaml.preserve_quotes = True
    yaml.representer.add_representer(
        type(None), lambda r, _: r.represent_scalar("tag:yaml.org,2002:null", "null"))
    return yaml


def _put(doc: CommentedMap, entry: dict, position: int | None) -> None:
    """The entry into ``doc``'s table: in place of the set at ``position``, or appended."""
    gravity = doc.get("gravity")
    if gravity is None:
        gravity = doc["gravity"] = CommentedMap()
    table = gravity.get("payloads")
    if not isinstance(table, CommentedSeq):
        table = gravity["payloads"] = CommentedSeq()
    new = _block(entry)
    if position is not None:
        old = table[position]
        for key in [k for k in old if k not in new]:
            del old[key]
        for key, value in new.items():
            old[key] = value
        return
    # a blank line after the table belongs to its last line's comment in ruamel's model: it moves to the
    # new last line, so the new set sits in the table and the blank line after it
    slot = _tail(table, gravity, "payloads")
    blank = ""
    if slot is not None and slot[0][slot[1]] is not None:
        token = slot[0][slot[1]]
        kept = token.value.rstrip("\n")
        blank = token.value[len(kept) + 1:]
        token.value = kept + "\n" if kept else "\n"
        if not kept and blank:
            slot[0][slot[1]] = None
    table.fa.set_block_style()
    table.append(new)
    if blank:
        last = list(new)[-1]
        new.ca.items[last] = [None, None, CommentToken("\n" + blank, _mark(), None), None]


def _mark():
    from ruamel.yaml.error import CommentMark

    return CommentMark(0)


def _tail(node, parent: CommentedMap, key) -> tuple[list, int] | None:
    """The comment slot after ``node``'s last line ([slots], position), which holds the blank lines that
    follow it; ``parent[key]`` is ``node``. None when nothing follows."""
    block = isinstance(node, (CommentedMap, CommentedSeq)) and len(node) and not node.fa.flow_style()
    if not block:       # a sequence keeps an item's end-of-line comment first, a mapping third
        position = 0 if isinstance(parent, CommentedSeq) else 2
        return parent.ca.items.setdefault(key, [None] * (2 if position == 0 else 4)), position
    last = list(node)[-1] if isinstance(node, CommentedMap) else len(node) - 1
    return _tail(node[last], node, last)


def _block(entry: dict) -> CommentedMap:
    """The entry as a block mapping whose number lists are written in flow style: [x, y, z]."""
    out = CommentedMap()
    for key, value in entry.items():
        if isinstance(value, (list, tuple)):
            value = CommentedSeq(value)
            value.fa.set_flow_style()
        out[key] = value
    return out


def _replace_checked(path: Path, text: str) -> None:
    """``path`` replaced by ``text`` once the service accepts it as a config; else unchanged."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".yaml", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        try:
            load_config(tmp)
        except ServiceConfigError as e:
            raise ServiceConfigError(str(e).replace(tmp, str(path))) from e
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
