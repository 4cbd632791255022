"""docs/deploy.md's systemd units, their `ExecStart` lines run as systemd would run them (issue 35, item 11).

The unit files are read from the page's own ```ini blocks (each opens with its path, ``# /etc/systemd/system/
NAME``). An `ExecStart=` line becomes a command as systemd makes it: specifiers (``%%``), words split at
blanks with quotes taken off, ``$$`` written as ``$`` and ``$NAME``/``${NAME}`` from the unit's
`Environment=` (none here, so empty); anything these rules do not cover fails the test rather than being
guessed. The command then runs with systemd's `PATH` for services and nothing else of this shell's: the
page's venv (``/opt/stiffcomp/.venv``) becomes this project's and its config path the test's file, and
nothing more is changed. There is no systemd here, so `systemctl` is the one program replaced, by a
stand-in at the front of that `PATH` that records its arguments.

What must hold: the service unit's command starts a real service, which SIGTERM ends with code 0; the
probe's command says live (exit 0) and restarts nothing while it runs; once it stopped, not live (exit 1)
and one `systemctl try-restart` of the service's unit (never `restart`, which would start a service an
operator stopped); with a config the probe refuses (exit 2), no restart at all, and the service unit's
command refuses that config with an exit code its `RestartPreventExitStatus=` names.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from hil.testing import ROOT, free_port, write_config
from testlib.common import wait_for
from tools.health_cmd import check

pytestmark = pytest.mark.realtime

DOC = ROOT / "docs" / "deploy.md"
SYSTEMD_PATH = "/usr/local/sbin:/usr/local/bin:/usr/sbin:/usr/bin:/sbin:/bin"
DOC_VENV = "/opt/stiffcomp/.venv"
DOC_CONFIG = "/etc/stiffcomp/service.yaml"
SERVICE, PROBE, TIMER = "stiffcomp.service", "stiffcomp-live.service", "stiffcomp-live.timer"


def unit(name: str) -> dict[str, dict[str, list[str]]]:
    """The unit file ``name`` as the page gives it: section -> key -> its values, in order."""
    blocks = re.findall(r"```ini\n(.*?)```", DOC.read_text(), re.DOTALL)
    found = [b for b in blocks if b.startswith(f"# /etc/systemd/system/{name}\n")]
    assert len(found) == 1, f"{DOC} has {len(found)} ```ini blocks for /etc/systemd/system/{name}"
    sections: dict[str, dict[str, list[str]]] = {}
    current = None
    for line in found[0].splitlines():
        line = line.strip()
        if not line or line[0] in "#;":
            continue
        if line.startswith("["):
            current = sections.setdefault(line.strip("[]"), {})
            continue
        key, _, value = line.partition("=")
        assert current is not None and _, f"{name}: {line!r} is no key=value in a section"
        current.setdefault(key.strip(), []).append(value.strip())
    return sections


def _expand_env(word: str, env: dict[str, str]) -> str:
    """systemd's environment expansion in one word: ``$$`` is ``$``, ``${NAME}`` and ``$NAME`` the value."""
    def one(m: re.Match) -> str:
        if m.group(0) == "$$":
            return "$"
        return env.get(m.group(1) or m.group(2), "")
    return re.sub(r"\$\$|\$\{([A-Za-z_][A-Za-z0-9_]*)\}|\$([A-Za-z_][A-Za-z0-9_]*)", one, word)


def exec_argv(line: str, unit_env: dict[str, str]) -> list[str]:
    """The argv systemd runs for one `ExecStart=` value (the subset of its rules these units use)."""
    assert "\\" not in line, f"{line!r}: escapes are beyond what this test reads as systemd does"
    assert re.sub("%%", "", line).count("%") == 0, f"{line!r}: a specifier other than %% is not expected"
    words = shlex.split(line.replace("%%", "%"), posix=True)
    assert ";" not in words, f"{line!r}: a lone ; would make several commands"
    assert words and words[0][0] not in "-@:+!", f"{line!r}: an executable prefix is not expected"
    return [_expand_env(w, unit_env) for w in words]


def _env(unit_sections: dict, path: str) -> tuple[dict[str, str], dict[str, str]]:
    """(the unit's Environment=, the process environment: systemd's PATH, plus the thread limits and the
    compiled cycle's cache of this test run, so that nothing compiles again)."""
    unit_env = dict(v.split("=", 1) for v in unit_sections["Service"].get("Environment", []))
    keep = ("HOME", "OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "STIFFCOMP_KERNEL_CACHE", "NUMBA_CACHE_DIR",
            "XDG_CACHE_HOME")
    env = {k: os.environ[k] for k in keep if k in os.environ}
    return unit_env, {**env, **unit_env, "PATH": path, "LANG": "C.UTF-8"}


def command(name: str, config: Path, path: str) -> tuple[list[str], dict[str, str]]:
    """The unit's single ExecStart command, the page's venv and config replaced by this project's and
    ``config``, and the environment to run it in."""
    sections = unit(name)
    (line,) = sections["Service"]["ExecStart"]
    unit_env, env = _env(sections, path)
    argv = [w.replace(DOC_VENV, sys.prefix).replace(DOC_CONFIG, str(config)) for w in exec_argv(line, unit_env)]
    exe = argv[0] if "/" in argv[0] else shutil.which(argv[0], path=SYSTEMD_PATH)
    assert exe and Path(exe).is_file(), f"{name}: {argv[0]} is not found on systemd's PATH {SYSTEMD_PATH}"
    return argv, env


class Probe:
    """The probe unit's command with a stand-in `systemctl` that writes its arguments, one call a line."""

    def __init__(self, folder: Path):
        bin_dir = folder / "bin"
        bin_dir.mkdir()
        self.calls = folder / "systemctl.calls"
        stand_in = bin_dir / "systemctl"
        stand_in.write_text(f'#!/bin/sh\necho "$*" >> {shlex.quote(str(self.calls))}\n')
        stand_in.chmod(0o755)
        self.path = f"{bin_dir}:{SYSTEMD_PATH}"

    def run(self, config: Path) -> tuple[int, str, list[str]]:
        """(exit code, output, the systemctl calls it made)."""
        self.calls.unlink(missing_ok=True)
        argv, env = command(PROBE, config, self.path)
        r = subprocess.run(argv, env=env, capture_output=True, text=True, timeout=60, check=False)
        calls = self.calls.read_text().splitlines() if self.calls.exists() else []
        return r.returncode, (r.stdout + r.stderr).strip(), calls


def test_the_units_of_deploy_md_restart_only_a_service_that_is_not_live(tmp_path):
    service_unit, timer = unit(SERVICE), unit(TIMER)
    assert timer["Timer"].get("OnUnitInactiveSec") or timer["Timer"].get("OnUnitActiveSec"), timer
    http, modbus = free_port(), free_port()
    cfg = write_config(tmp_path, {"plc": {"port": modbus}, "monitoring": {"port": http},
                                  "cycle": {"stats_log_interval_s": 0}})
    bad = tmp_path / "bad.yaml"
    bad.write_text(yaml.safe_dump({"monitoring": {"port": "http"}}))
    probe = Probe(tmp_path)

    argv, env = command(SERVICE, cfg, SYSTEMD_PATH)
    assert service_unit["Service"]["KillSignal"] == ["SIGTERM"]
    service = subprocess.Popen(argv, env=env, cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        assert wait_for(lambda: service.poll() is not None or check("127.0.0.1", http, probe="live")[0], 90.0)
        assert service.poll() is None, f"the service unit's command ended with code {service.returncode}"
        # a machine with both cores busy may stall the cycle for a second now and then, which the probe
        # rightly calls not live: probe until it says live, and every run must restart exactly when not live
        runs = []
        assert wait_for(lambda: runs.append(probe.run(cfg)) or runs[-1][0] == 0, 60.0, every=0.2), runs
        assert runs[-1][1].startswith("live: "), runs[-1]
        assert all(calls == ([] if code == 0 else [f"try-restart {SERVICE}"]) for code, _, calls in runs), runs
    finally:
        service.send_signal(signal.SIGTERM)
        assert service.wait(timeout=20) == 0             # the unit's TimeoutStopSec

    code, out, calls = probe.run(cfg)
    assert code == 1 and out.startswith("not live: "), (code, out)
    assert calls == [f"try-restart {SERVICE}"], calls

    code, out, calls = probe.run(bad)
    assert code == 2 and "monitoring.port" in out and calls == [], (code, out, calls)
    argv, env = command(SERVICE, bad, SYSTEMD_PATH)
    refused = subprocess.run(argv, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=120, check=False)
    prevent = service_unit["Service"]["RestartPreventExitStatus"][0].split()
    assert str(refused.returncode) in prevent, (refused.returncode, prevent, refused.stderr[-300:])
