"""pyproject.toml declares its licence as an SPDX expression, with a setuptools that reads one, so an
install prints no `project.license` deprecation block (issue 17, item 8)."""

from __future__ import annotations

import re
import tomllib
from pathlib import Path

PYPROJECT = tomllib.loads((Path(__file__).resolve().parents[2] / "pyproject.toml").read_text())


def test_the_license_is_an_spdx_string():
    assert PYPROJECT["project"]["license"] == "Apache-2.0"


def test_the_build_asks_for_a_setuptools_that_reads_spdx_licenses():
    req = next(r for r in PYPROJECT["build-system"]["requires"] if r.startswith("setuptools"))
    m = re.fullmatch(r"setuptools>=(\d+)(?:\.\d+)*", req)
    assert m and int(m.group(1)) >= 77, req          # setuptools 77 (PEP 639) reads license = "SPDX"
