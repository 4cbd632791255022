"""deploy/remove_pip.sh, the image's step that removes the base's own pip (issue 45, item 7), against stand-ins of
each kind of base: Debian's python3-pip (pip refuses it, PEP 668: apt-get must purge it), python:3.11-slim's
pip (pip uninstalls itself), no pip at all (nothing runs), and a pip that will not go (the step fails, naming it).

The stand-ins are small shell scripts on PATH that behave as the real commands do for what the step asks: a
`python3` whose ``-m pip --version`` answers while a marker file exists and whose ``-m pip uninstall`` removes
it, or refuses as Debian's does ("externally-managed-environment") where the pip is the distribution's; a
`dpkg-query` that reports python3-pip installed or not; an `apt-get` whose purge of python3-pip removes the
marker. Every call is logged, so the test sees what the step ran.
"""

from __future__ import annotations

import shutil
import subprocess

import pytest

from hil.testing import ROOT

STEP = ROOT / "deploy" / "remove_pip.sh"

PYTHON = r"""#!/bin/sh
echo "python3 $*" >> "$STAND/calls"
if [ "$1 $2" = "-m pip" ]; then
    [ -e "$STAND/pip" ] || { echo "No module named pip" >&2; exit 1; }
    case "$3" in
    --version) echo "pip 23.0.1 from $(cat "$STAND/pip")"; exit 0 ;;
    uninstall)
        if [ "$(cat "$STAND/pip")" = debian ]; then
            if [ -z "${PIP_BREAK_SYSTEM_PACKAGES:-}" ]; then
                echo "error: externally-managed-environment" >&2; exit 1
            fi
            echo "error: Cannot uninstall pip 23.0.1, RECORD file not found. Hint: installed by debian." >&2
            exit 1
        fi
        [ "$(cat "$STAND/pip")" = stuck ] && exit 0
        rm "$STAND/pip"; exit 0 ;;
    esac
fi
exit 0
"""

DPKG_QUERY = r"""#!/bin/sh
echo "dpkg-query $*" >> "$STAND/calls"
for last; do :; done
if [ -e "$STAND/$last" ]; then printf 'install ok installed'; exit 0; fi
echo "dpkg-query: no packages found matching $last" >&2; exit 1
"""

# purge -s prints what a purge would remove ("Purg NAME [version]"), the packages named and, where the base
# needs setuptools ($STAND/needs), the package that depends on it; a real purge removes the packages named
APT_GET = r"""#!/bin/sh
echo "apt-get $*" >> "$STAND/calls"
if [ "$1 $2" = "purge -s" ]; then
    shift 2
    for p; do echo "Purg $p [1.0]"; done
    [ -e "$STAND/needs" ] && echo "Purg python3-foo [2.0]"
    exit 0
fi
for p; do case "$p" in python3-*) rm -f "$STAND/$p"; [ "$p" = python3-pip ] && rm -f "$STAND/pip" ;; esac; done
exit 0
"""


@pytest.fixture
def base(tmp_path):
    """A folder of stand-ins and the function that runs the step on them with pip as ``kind`` (None: no pip)."""
    bin_, tools = tmp_path / "bin", tmp_path / "tools"
    bin_.mkdir()
    tools.mkdir()
    for name, text in (("python3", PYTHON), ("dpkg-query", DPKG_QUERY), ("apt-get", APT_GET)):
        (bin_ / name).write_text(text)
        (bin_ / name).chmod(0o755)
    for name in ("sh", "grep", "sed", "cat", "rm"):            # the only real commands on PATH: none of this host's own
        (tools / name).symlink_to(shutil.which(name))

    def run(kind: str | None, dpkg: bool = True, needs: bool = False) -> tuple[subprocess.CompletedProcess, list[str]]:
        (tmp_path / "calls").write_text("")
        if kind is not None:
            (tmp_path / "pip").write_text(kind)
        if kind == "debian":                    # the Debian packages the base has: pip and what it pulls in
            for name in ("python3-pip", "python3-setuptools", "python3-wheel"):
                (tmp_path / name).write_text("")
        if needs:
            (tmp_path / "needs").write_text("")
        if not dpkg:
            (bin_ / "dpkg-query").unlink()
        env = {"PATH": f"{bin_}:{tools}", "STAND": str(tmp_path)}
        p = subprocess.run([str(tools / "sh"), str(STEP)], env=env, capture_output=True, text=True, timeout=30,
                           check=False)
        return p, (tmp_path / "calls").read_text().splitlines()

    return run


def test_debians_python3_pip_is_purged_with_apt_get(base, tmp_path):
    """With what it pulled in (setuptools, wheel: the image test wants neither in the base's Python)."""
    p, calls = base("debian")
    assert p.returncode == 0, p.stderr
    assert not (tmp_path / "pip").exists()                              # the image has no pip
    assert "apt-get purge -y -q python3-pip python3-setuptools python3-wheel" in calls
    assert not any(c.startswith("python3 -m pip uninstall") for c in calls)     # which pip would have refused
    assert not any((tmp_path / n).exists() for n in ("python3-pip", "python3-setuptools", "python3-wheel"))


def test_setuptools_that_the_base_needs_stays(base, tmp_path):
    """A purge that would remove another of the base's packages removes python3-pip alone, and says so."""
    p, calls = base("debian", needs=True)
    assert p.returncode == 0, p.stderr
    assert "apt-get purge -y -q python3-pip" in calls and not (tmp_path / "pip").exists()
    assert "keeping python3-setuptools and python3-wheel: the base needs them (python3-foo)" in p.stdout
    assert (tmp_path / "python3-setuptools").exists()


def test_the_slim_images_pip_uninstalls_itself(base, tmp_path):
    for dpkg in (True, False):                                           # python:3.11-slim has dpkg; others not
        p, calls = base("pip", dpkg=dpkg)
        assert p.returncode == 0, p.stderr
        assert not (tmp_path / "pip").exists()
        assert "python3 -m pip uninstall -y -q pip setuptools wheel" in calls
        assert not any(c.startswith("apt-get") for c in calls)


def test_a_base_without_pip_runs_nothing(base):
    p, calls = base(None)
    assert p.returncode == 0 and calls == ["python3 -m pip --version"], (p.stderr, calls)


def test_a_pip_that_stays_fails_the_step_naming_it(base):
    p, _ = base("stuck")
    assert p.returncode != 0 and "pip is still in the base image: pip 23.0.1" in p.stderr


def test_the_dockerfile_runs_the_step_in_the_runtime_stage_before_the_venv():
    text = (ROOT / "Dockerfile").read_text()
    runtime = text[text.index("FROM ${BASE}\n"):]
    assert runtime.index("RUN sh /tmp/remove_pip.sh") < runtime.index("COPY --from=build /opt/venv")
    assert runtime.index("RUN sh /tmp/remove_pip.sh") < runtime.index("USER stiffcomp")        # as root
    assert "!deploy/remove_pip.sh" in (ROOT / ".dockerignore").read_text().splitlines()        # in the context
