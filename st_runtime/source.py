"""Reading TwinCAT sources with blark (TwinCAT's structured-text grammar): each file parsed once per content.

Parsing is the slow part of loading a program (seconds for a function block; every HIL pass starts a PLC
process that loads one), so the parse results are kept, per file content and blark version, in memory for the
process and pickled on disk (`cache_dir`: ``$STIFFCOMP_CACHE``, else ``$XDG_CACHE_HOME/stiffcomp``, else
``~/.cache/stiffcomp``; st-runtime/ in it). A cache entry that cannot be read is parsed again and rewritten.
"""

from __future__ import annotations

import functools
import hashlib
import os
import pickle
from importlib.metadata import version
from pathlib import Path

from blark.parse import parse

from .values import StError


def cache_dir() -> Path:
    root = os.environ.get("STIFFCOMP_CACHE") or Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") \
        / "stiffcomp"
    return Path(root) / "st-runtime"


def parse_file(path: Path) -> list:
    """The blark parse results of one TwinCAT file; `StError` naming the file when any part fails."""
    return list(_parsed(str(path), hashlib.sha256(Path(path).read_bytes()).hexdigest()))


@functools.cache
def _parsed(path: str, digest: str) -> tuple:
    cached = cache_dir() / f"{version('blark')}-{digest}.pickle"
    try:
        results = pickle.loads(cached.read_bytes())
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, ImportError, TypeError):
        results = None
    if results is None:
        results = _parse(path)
        try:
            cached.parent.mkdir(parents=True, exist_ok=True)
            tmp = cached.with_suffix(f".{os.getpid()}.tmp")
            tmp.write_bytes(pickle.dumps(results))
            os.replace(tmp, cached)
        except OSError:
            pass                                        # a read-only home: parse each time
    return tuple(results)


def _parse(path: str) -> list:
    results = list(parse(path))
    if not results:
        raise StError(f"{path}: blark found nothing to parse")
    for r in results:
        if r.exception is not None:
            raise StError(f"{path}: blark: {r.exception}")
    return results
