"""`make image-test` builds the image `make image` built: the base and the CA folder given to `make image`
are remembered, so the test's build (a rebuild from Docker's cache) needs them no more (issue 35, item 17).

Without Docker: ``make -n`` prints the recipes. `make image`'s line that writes the remembered values runs
as make would run it (``sh -c``) into a temporary file named by ``IMAGE_ARGS``, and `make -n image-test`
with that file must then build with the same ``BASE`` and copy the same certificates, unless the command
line says otherwise.
"""

from __future__ import annotations

import re
import shutil
import subprocess

import pytest

from hil.testing import ROOT

pytestmark = pytest.mark.skipif(shutil.which("make") is None, reason="make is not installed")


def dry_run(*args: str) -> list[str]:
    """The recipe lines make would run, a line continued with a backslash joined to the next (as the shell
    gets it: make drops the continued line's leading tab)."""
    r = subprocess.run(["make", "-n", "--no-print-directory", *args], cwd=ROOT, capture_output=True, text=True,
                       timeout=60, check=True)
    return re.split(r"(?<!\\)\n", r.stdout.replace("\\\n\t", "\\\n"))


def build_line(lines: list[str]) -> str:
    (line,) = [x for x in lines if x.startswith("docker build")]
    return line


def test_image_test_builds_with_what_make_image_was_given(tmp_path):
    args = tmp_path / "image-args.mk"
    certs = tmp_path / "site-certs"
    image = dry_run("image", "BASE=stiffcomp-base:bookworm", f"CA_CERTS_DIR={certs}", "IMAGE=stiffcomp:cell7",
                    f"IMAGE_ARGS={args}")
    writes = [x for x in image if str(args) in x]
    assert len(writes) == 1, image
    subprocess.run(["sh", "-c", writes[0]], cwd=tmp_path, check=True, timeout=10)

    test = dry_run("image-test", f"IMAGE_ARGS={args}")
    assert "--build-arg BASE=stiffcomp-base:bookworm " in build_line(test)
    assert build_line(test).endswith("-t stiffcomp:cell7 .")
    assert any(x.startswith("cp ") and str(certs) in x for x in test), test
    assert any("image_test.py --image stiffcomp:cell7" in x for x in test), test

    # the command line still wins over what was remembered, and nothing remembered means the defaults
    assert "--build-arg BASE=python:3.11-slim " in build_line(dry_run("image-test", f"IMAGE_ARGS={args}",
                                                                        "BASE=python:3.11-slim"))
    fresh = dry_run("image-test", f"IMAGE_ARGS={tmp_path / 'none.mk'}")
    assert "--build-arg BASE=python:3.11-slim " in build_line(fresh)
    assert not any(x.startswith("cp ") for x in fresh), fresh


def slug(heading: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, blanks as hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def test_the_dockerfile_cites_sections_the_docs_have():
    cited = re.findall(r"docs/([\w-]+\.md)(?:#([\w-]+))?", (ROOT / "Dockerfile").read_text())
    assert ("deploy.md", "the-compiled-cycle") in cited
    for doc, anchor in cited:
        text = (ROOT / "docs" / doc).read_text()
        anchors = {slug(h) for h in re.findall(r"(?m)^#+ (.+)$", re.sub(r"(?s)```.*?```", "", text))}
        assert not anchor or anchor in anchors, f"Dockerfile cites docs/{doc}#{anchor}, which has no such heading"
