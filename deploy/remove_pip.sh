#!/bin/sh
# Remove the base image's own pip from the image's runtime stage (the Dockerfile runs it before the venv
# arrives, so `python3` is the base's): the shipped image carries no pip (docs/deploy.md, "Contents").
#
# Two kinds of base carry one, and each is removed by the tool that installed it:
#
# * Debian's or Ubuntu's `python3-pip` (a Debian base with pip, the Ubuntu images): a package of the
#   distribution. pip itself refuses to touch it: the interpreter is marked EXTERNALLY-MANAGED (PEP 668,
#   "error: externally-managed-environment"), and Debian's packages ship no RECORD file for pip to uninstall
#   by. So apt-get purges it, with python3-setuptools and python3-wheel (which it pulls in) where nothing else
#   of the base needs them: a simulated purge must remove no other package, or only python3-pip goes.
# * pip installed by pip or ensurepip (python:3.11-slim's /usr/local): pip uninstalls itself, setuptools and
#   wheel; where the interpreter is marked externally managed anyway, PIP_BREAK_SYSTEM_PACKAGES=1 lets it,
#   as nothing of the distribution's is touched.
#
# Exits non-zero, naming what is left, when pip is still there afterwards. PYTHON (default python3) is the
# interpreter asked; tests/tools/test_remove_pip.py runs this file against stand-ins of each kind.
set -eu
PY=${PYTHON:-python3}

has_pip() { "$PY" -m pip --version >/dev/null 2>&1; }

installed() {   # a Debian package of that name is installed
    command -v dpkg-query >/dev/null 2>&1 &&
        dpkg-query -W -f='${Status}' "$1" 2>/dev/null | grep -q ' installed$'
}

has_pip || exit 0

if installed python3-pip; then
    echo "remove_pip: purging Debian's python3-pip (pip refuses a distribution's package, PEP 668)"
    PKGS=python3-pip
    for p in python3-setuptools python3-wheel; do installed "$p" && PKGS="$PKGS $p"; done
    OTHERS=$(apt-get purge -s $PKGS 2>/dev/null | sed -n 's/^Purg \([^ ]*\).*/\1/p' |
             grep -v -x -e python3-pip -e python3-setuptools -e python3-wheel || true)
    if [ -n "$OTHERS" ]; then
        echo "remove_pip: keeping python3-setuptools and python3-wheel: the base needs them ($(echo $OTHERS))"
        PKGS=python3-pip
    fi
    DEBIAN_FRONTEND=noninteractive apt-get purge -y -q $PKGS
fi
if has_pip; then
    echo "remove_pip: uninstalling the base's pip, setuptools and wheel with pip"
    PIP_BREAK_SYSTEM_PACKAGES=1 "$PY" -m pip uninstall -y -q pip setuptools wheel
fi
if has_pip; then
    echo "remove_pip: pip is still in the base image: $("$PY" -m pip --version 2>&1)" >&2
    exit 1
fi
