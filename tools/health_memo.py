"""The health probe's memory of a config it has validated: so that the probe an orchestrator runs every few
seconds validates the file with the service's schemas once, not at every run (docs/deploy.md#the-probes-cost).

`stiffcomp health` reads the ``monitoring``, ``plc`` and ``ads`` sections with the service's own schemas
(`plc_interface.endpoints.read_endpoints`), which imports pydantic and builds the schemas: some 0.15 s of a
probe that otherwise costs the interpreter's start and one HTTP request. After a validation that passed, it
writes a small JSON file beside the run file (`tools.run_file.run_dir`)::

    {"version": 1, "config": "/etc/stiffcomp/service.yaml", "sha256": "<the file's bytes>",
     "code": "<the schemas' source files: size and mtime of each>", "monitoring": {"host": ..., "port": ...}}

and a later probe of the same config whose bytes and schema code are the same takes ``monitoring`` from it
without importing pydantic or pyyaml. Any change of the file (a key edited, a section misspelt) or of the
schemas' code (an upgrade) misses the memo, so that probe validates again and refuses what the service
refuses, word for word. Only the HTTP path is remembered (``monitoring.enabled``); the Modbus and ADS fallbacks
import far more than the schemas anyway. A run folder that cannot be written only costs the speed.
"""

from __future__ import annotations

import hashlib
import json
import os
from pathlib import Path

from .run_file import run_dir

VERSION = 1
ROOT = Path(__file__).resolve().parent.parent
# what decides the probe's reading of a config: the schemas of its sections, their defaults, the known
# sections, the YAML loader and the reader itself
CODE = ("plc_interface/settings.py", "plc_interface/ads/settings.py", "plc_interface/ads/ams.py",
        "plc_interface/endpoints.py", "service/paths.py", "stiffness/files/yaml_syntax.py",
        "stiffness/files/yaml_schema.py", "tools/health_memo.py")


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


def code_key() -> str:
    """The schemas' source files as they are installed now: size and mtime of each."""
    parts = []
    for rel in CODE:
        try:
            st = (ROOT / rel).stat()
            parts.append(f"{rel}:{st.st_size}:{st.st_mtime_ns}")
        except OSError:
            parts.append(f"{rel}:-")
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()


def recall(config: str | Path) -> tuple[str, int] | None:
    """(monitoring.host, monitoring.port) of ``config`` as a validation found them, when neither the file nor
    the schemas' code changed since; None otherwise (validate)."""
    path = memo_path(config)
    try:
        if any(p.stat().st_uid != os.getuid() for p in (path.parent, path)):
            return None             # a folder or memo another user made (/tmp is shared): not trusted
        memo = json.loads(path.read_text())
        if memo.get("version") != VERSION or memo.get("sha256") != digest(config) or memo.get("code") != code_key():
            return None
        host, port = memo["monitoring"]["host"], memo["monitoring"]["port"]
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if not isinstance(host, str) or not isinstance(port, int):
        return None
    return host, port


def remember(config: str | Path, sha256: str, host: str, port: int) -> None:
    """Keep what a validation of ``config`` (its bytes' ``sha256``, hashed before the validation read them)
    found; nothing when the file changed meanwhile or the run folder cannot be written."""
    if sha256 != digest(config):
        return
    memo = {"version": VERSION, "config": str(Path(config).resolve()), "sha256": sha256, "code": code_key(),
            "monitoring": {"host": host, "port": port}}
    path = memo_path(config)
    try:
        path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
        tmp = path.with_suffix(f".{os.getpid()}.tmp")
        tmp.write_text(json.dumps(memo) + "\n")
        os.replace(tmp, path)
    except OSError:
        pass
