"""The run file: how `stiffcomp reload` finds the service that `stiffcomp run` started with a config.

`stiffcomp run --config FILE` writes a small JSON file named after FILE's absolute path, in the run
folder (``$STIFFCOMP_RUN_DIR``, else ``$XDG_RUNTIME_DIR/stiffcomp``, else ``/tmp/stiffcomp-<uid>``)::

    {"pid": 4711, "config": "/etc/stiffcomp/site.yaml",
     "reloads": {"attempts": 2, "accepted": 1, "last": {"accepted": false, "message": "reload of ..."}}}

and rewrites it (atomically) after each reload. While the service runs it holds an exclusive lock on
the file's ``.lock`` companion, so a file left by a service that was killed is recognised as stale
(its lock is free), never mistaken for a running service, whatever process has its pid now. The
service removes both files when it ends.
"""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import tempfile
from pathlib import Path


def run_dir() -> Path:
    if os.environ.get("STIFFCOMP_RUN_DIR"):
        return Path(os.environ["STIFFCOMP_RUN_DIR"])
    if os.environ.get("XDG_RUNTIME_DIR"):
        return Path(os.environ["XDG_RUNTIME_DIR"]) / "stiffcomp"
    return Path(tempfile.gettempdir()) / f"stiffcomp-{os.getuid()}"


def run_file_for(config: str | Path) -> Path:
    """The run file of the service started with ``config`` (by its absolute path)."""
    key = hashlib.sha1(str(Path(config).resolve()).encode()).hexdigest()[:16]
    return run_dir() / f"{key}.json"


class RunFile:
    """The running service's side: `claim` at start, `write` after each reload, `release` at the end."""

    def __init__(self, config: str | Path):
        self.config = str(Path(config).resolve())
        self.path = run_file_for(config)
        self.lock_path = self.path.with_suffix(".lock")
        self._lock = None

    def claim(self) -> bool:
        """Take the lock; False when another running service holds it (it keeps its run file) or the run
        folder cannot be written (then only SIGHUP reloads)."""
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True, mode=0o700)
            f = self.lock_path.open("a")
        except OSError:
            return False
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            return False
        self._lock = f
        return True

    def write(self, service) -> None:
        """The service's pid and its reloads so far (`service.app.Service`)."""
        if self._lock is None:
            return
        last = service.last_reload
        state = {"pid": os.getpid(), "config": self.config,
                 "reloads": {"attempts": service.reload_attempts, "accepted": service.cycle.reloads,
                             "last": None if last is None else {"accepted": last.accepted, "message": last.message}}}
        tmp = self.path.with_suffix(".tmp")
        tmp.write_text(json.dumps(state) + "\n")
        os.replace(tmp, self.path)

    def release(self) -> None:
        if self._lock is None:
            return
        self.path.unlink(missing_ok=True)
        self.lock_path.unlink(missing_ok=True)
        self._lock.close()
        self._lock = None


def read_run_file(config: str | Path) -> dict | None:
    """The run file of the service running with ``config``, or None (none, or stale: its lock is free)."""
    path = run_file_for(config)
    try:
        with path.with_suffix(".lock").open("r") as f:
            try:
                fcntl.flock(f, fcntl.LOCK_SH | fcntl.LOCK_NB)
            except OSError:
                return json.loads(path.read_text())        # locked: the service runs
            return None
    except (OSError, ValueError):
        return None
