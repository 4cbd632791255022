"""The health probe's memory of a config it has validated: so that the probe an orchestrator runs every few
seconds validates the file with the service's schemas once, not at every run (docs/deploy.md#the-probes-cost).

`stiffcomp health` reads the ``monitoring``, ``plc`` and ``ads`` sections with the service's own schemas
(`io_process.endpoints.read_endpoints`), which imports pydantic and builds the schemas: some 0.15 s of a
probe that otherwise costs the interpreter's start and one HTTP request. After a validation that passed, it
writes a small JSON file beside the run file (`tools.run_file.run_dir`)::

    {"version": 2, "config": "/etc/stiffcomp/service.yaml", "sha256": "<the file's bytes>",
     "files": ["io_process/endpoints.py", ...], "code": "<size and mtime of each of those files>",
     "monitoring": {"host": ..., "port": ...}}

``files`` are the source files of every module the validation had imported from the project's packages
(`imported_files`: found in ``sys.modules``, not listed by hand), so they are the code that decided the
reading: the schemas, their defaults, the known sections, the YAML loader, this reader. A later probe of
the same config whose bytes and those files are the same takes ``monitoring`` from the memo without
importing pydantic or pyyaml. Any change of the file (a key edited, a section misspelt) or of that code (an
upgrade; a module newly imported is imported by one of them, which changed too) misses the memo, so that
probe validates again and refuses what the service refuses, word for word. Only the HTTP path is remembered
(``monitoring.enabled``); the Modbus and ADS fallbacks import far more than the schemas anyway. A run folder
that cannot be written only costs the speed.
"""

from __future__ import annotations

import hashlib
import json
import os
import sys
from pathlib import Path

from .run_file import run_dir

VERSION = 2
ROOT = Path(__file__).resolve().parent.parent       # where the project's packages are installed


def memo_path(config: str | Path) -> Path:
    """The memo of ``config`` (by its absolute path) in the run folder."""
    key = hashlib.sha1(str(Path(config).resolve()).encode()).hexdigest()[:16]
    return run_dir() / f"{key}.probe.json"


def digest(config: str | Path) -> str | None:
    """The sha256 of the config file's bytes, or None when it cannot be read (the validation then says why)."""
    try:
        return hashlib.sha256(Path(config).read_bytes()).hexdigest()
    except OSError:
        return None


def imported_files() -> list[str]:
    """The source file of every module this process has imported from a package installed in `ROOT` (the
    folder that holds `tools`), relative to it, sorted. In a source tree or an editable install these are the
    project's own packages; beside a wheel in site-packages, the libraries there too, which only makes the
    key stricter."""
    # the project's modules lie where this one was imported from (its path as read, links kept), or in `ROOT`
    imported_from = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    roots = {os.path.join(imported_from, ""), os.path.join(ROOT, "")}
    found = set()
    for name, module in list(sys.modules.items()):
        path = getattr(module, "__file__", None)
        root = next((r for r in roots if path and path.startswith(r)), None)
        if root is None:
            continue
        rel = path[len(root):]
        if rel.split(os.sep, 1)[0] == name.partition(".")[0]:     # its own package's folder, not a venv's
            found.add(rel)
    return sorted(found)


def code_key(files: list[str]) -> str:
    """``files`` (relative to `ROOT`) as they are installed now: size and mtime of each."""
    parts = []
    for rel in files:
        try:
            st = os.stat(os.path.join(ROOT, rel))
            parts.append(f"{rel}:{st.st_size}:{st.st_mtime_ns}")
        except OSError:
            parts.append(f"{rel}:-")
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()


def recall(config: str | Path) -> tuple[str, int] | None:
    """(monitoring.host, monitoring.port) of ``config`` as a validation found them, when neither the file nor
    the code that validation imported changed since; None otherwise (validate)."""
    path = memo_path(config)
    try:
        if any(p.stat().st_uid != os.getuid() for p in (path.parent, path)):
            return None             # a folder or memo another user made (/tmp is shared): not trusted
        memo = json.loads(path.read_text())
        files = memo.get("files")
        if memo.get("version") != VERSION or memo.get("sha256") != digest(config):
            return None
        if not isinstance(files, list) or not all(isinstance(f, str) for f in files):
            return None
        if memo.get("code") != code_key(files):
            return None
        host, port = memo["monitoring"]["host"], memo["monitoring"]["port"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not isinstance(host, str) or not isinstance(port, int):
        return None
    return host, port


def remember(config: str | Path, sha256: str, host: str, port: int) -> None:
    """Keep what a validation of ``config`` (its bytes' ``sha256``, hashed before the validation read them)
    found, keyed by the code it imported (`imported_files`: call this after the validation); nothing when the
    file changed meanwhile or the run folder cannot be written."""
    if sha256 != digest(config):
        return
    files = imported_files()
    memo = {"version": VERSION, "config": str(Path(config).resolve()), "sha256": sha256, "files": files,
            "code": code_key(files), "monitoring": {"host": host, "port": port}}
    path = memo_path(config)
    try:
        path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(memo) + "\n")
        os.replace(tmp, path)
    except OSError:
        pass
