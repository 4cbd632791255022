"""The HIL on a host whose only interface is loopback (issue 45, item 2): `hil circle` exits 2 before any process
starts, in one line saying what to run, with no traceback; after those commands the host carries the HIL's
multicast. The host is a network namespace of its own (`unshare -n`, loopback up), where the test may make
one; elsewhere it skips with one line."""

from __future__ import annotations

import shutil
import subprocess
import sys

import pytest

from hil.multicast import FIX
from hil.testing import ROOT


def _may_unshare() -> str | None:
    """Why this test cannot make a network namespace here, or None."""
    if shutil.which("unshare") is None or shutil.which("ip") is None:
        return "no unshare or ip command"
    p = subprocess.run(["unshare", "-n", "ip", "link", "set", "lo", "up"], capture_output=True, text=True,
                       check=False, timeout=30)
    return None if p.returncode == 0 else f"unshare -n is not permitted here ({p.stderr.strip()})"


WHY_NOT = _may_unshare()
pytestmark = pytest.mark.skipif(WHY_NOT is not None, reason=f"a loopback-only host needs a namespace: {WHY_NOT}")


def in_namespace(script: str, *, fixed: bool) -> subprocess.CompletedProcess:
    """``script`` (a shell line) in a fresh network namespace with loopback up, ``fixed``: after FIX."""
    setup = "ip link set lo up" + (f" && {FIX}" if fixed else "")
    return subprocess.run(["unshare", "-n", "sh", "-c", f"{setup} && {script}"], cwd=ROOT, capture_output=True,
                          text=True, check=False, timeout=120)


def test_hil_circle_on_a_loopback_only_host_says_what_to_run_before_any_process(tmp_path):
    report = tmp_path / "report"
    p = in_namespace(f"{sys.executable} -m tools.cli hil circle --report {report}", fixed=False)
    lines = p.stderr.strip().splitlines()
    assert p.returncode == 2 and len(lines) == 1 and "Traceback" not in p.stderr, p.stderr
    assert lines[0].startswith("stiffcomp hil: error: ") and FIX in lines[0] and "--lockstep" in lines[0]
    assert "service" not in p.stdout and not report.exists()                 # nothing ran, nothing written


def test_after_the_commands_the_host_carries_the_hils_multicast():
    check = "from hil.multicast import check_multicast; check_multicast('239.74.1.2', 47999); print('carried')"
    p = in_namespace(f"{sys.executable} -c \"{check}\"", fixed=True)
    assert p.returncode == 0 and p.stdout.strip() == "carried", p.stderr
