"""Every relative link with an anchor in README.md and docs/*.md reaches a file that exists and a heading in it.

Anchors follow GitHub's rules for a heading: its text in lower case, markup and punctuation dropped (letters,
digits, '-', '_' and spaces kept), each space a '-'; a heading that repeats takes '-1', '-2', ... Links in
code (fenced blocks, `spans`) are not links and are left alone.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
FENCE = re.compile(r"^ {0,3}(```|~~~)")
HEADING = re.compile(r"^ {0,3}(#{1,6})\s+(.*?)\s*#*\s*$")
LINK = re.compile(r"\]\(\s*<?([^)\s>]*#[^)\s>]*)>?(?:\s+\"[^\"]*\")?\s*\)")
HTML_ID = re.compile(r"<a\s+(?:name|id)=\"([^\"]+)\"")


def prose(text: str) -> list[str]:
    """The lines outside fenced code blocks, inline code spans blanked."""
    out, fenced = [], False
    for line in text.splitlines():
        if FENCE.match(line):
            fenced = not fenced
            continue
        out.append("" if fenced else re.sub(r"(`+).*?\1", "", line))
    return out


def slug(heading: str) -> str:
    """GitHub's anchor of a heading's text."""
    text = re.sub(r"!?\[([^\]]*)\]\([^)]*\)", r"\1", heading)      # a link in a heading: its text
    text = re.sub(r"<[^>]+>", "", text).lower()
    return "".join(c for c in text if c.isalnum() or c in "-_ ").replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """The anchors a Markdown file offers: its headings' (repeats numbered) and its HTML ids."""
    found: set[str] = set()
    seen: dict[str, int] = {}
    text = path.read_text(encoding="utf-8")
    fenced = False
    for line in text.splitlines():
        if FENCE.match(line):
            fenced = not fenced
            continue
        m = None if fenced else HEADING.match(line)
        if m:
            base = slug(m.group(2))
            n = seen.get(base, 0)
            seen[base] = n + 1
            found.add(base if n == 0 else f"{base}-{n}")
    return found | set(HTML_ID.findall(text))


def links(path: Path) -> list[tuple[int, str]]:
    """(line, target) of each relative link with an anchor in ``path``."""
    return [(k, target) for k, line in enumerate(prose(path.read_text(encoding="utf-8")), 1)
            for target in LINK.findall(line) if not re.match(r"[a-z][a-z0-9+.-]*:", target)]


def broken(path: Path, root: Path = ROOT) -> list[str]:
    """Each link of ``path`` that does not resolve, and why (paths shown from ``root``)."""
    out = []
    for line, target in links(path):
        file, _, anchor = target.partition("#")
        dest = (path.parent / file).resolve() if file else path
        where = f"{path.relative_to(root)}:{line}: {target}"
        if not dest.is_file():
            out.append(f"{where}: no file {file}")
        elif dest.suffix == ".md" and anchor not in anchors(dest):
            out.append(f"{where}: {dest.relative_to(root)} has no heading with that anchor")
    return out


def test_the_anchor_rules():
    assert slug("Signals, and the two processes watching each other") == \
        "signals-and-the-two-processes-watching-each-other"
    assert slug("The trace of a cut (`--trace FILE`)") == "the-trace-of-a-cut---trace-file"
    assert slug("Figures (HIL, the paper's circle, ringing stub)") == "figures-hil-the-papers-circle-ringing-stub"
    assert slug("Preloaded backlash (hil/preload.py)") == "preloaded-backlash-hilpreloadpy"
    assert slug("Size: 1.3 GB – why") == "size-13-gb--why"


def test_the_checker_finds_a_broken_anchor_and_a_missing_file(tmp_path):
    (tmp_path / "a.md").write_text("# Title\n\n## The two, processes\n\n## Twice\n\n## Twice\n")
    (tmp_path / "b.md").write_text("[ok](a.md#the-two-processes) [ok](a.md#twice-1) [ok](#here)\n"
                                   "[bad](a.md#the-two-processes-watch) [bad](c.md#x) [web](https://x.org/a#b)\n"
                                   "`[code](a.md#not-a-link)`\n\n## Here\n")
    assert broken(tmp_path / "b.md", tmp_path) == [
        "b.md:2: a.md#the-two-processes-watch: a.md has no heading with that anchor", "b.md:2: c.md#x: no file c.md"]


@pytest.mark.parametrize("path", DOCS, ids=[str(p.relative_to(ROOT)) for p in DOCS])
def test_every_anchored_link_resolves(path):
    assert broken(path) == []
