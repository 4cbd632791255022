"""The README is a front door (issue 36, item 4): at most 200 lines, the walk exactly as `make walk` runs it,
and a map naming every page of docs/; the figures it no longer holds live in docs/benchmarks.md, which names
every benchmark script, each with options the script takes."""

from __future__ import annotations

import re

from testlib.common import ROOT

README = ROOT / "README.md"
BENCHMARKS = ROOT / "docs" / "benchmarks.md"
SCRIPT_RUN = re.compile(r"(bench_\w+\.py)((?: --[\w-]+(?: [\w.]+)?)*)")


def bash_blocks(text: str) -> list[str]:
    return re.findall(r"```bash\n(.*?)```", text, re.DOTALL)


def commands(block: str) -> list[str]:
    """The block's command lines after its first (the variables), comments dropped, blanks squeezed."""
    lines = [re.sub(r"\s+#.*$", "", line) for line in block.splitlines()[1:]]
    return [" ".join(line.split()) for line in lines if line.strip()]


def makefile_walk() -> tuple[str, list[str]]:
    """The campaign `make walk` reads, and its recipe's commands as the README writes them ($S, $D)."""
    text = (ROOT / "Makefile").read_text()
    data = re.search(r"^WALK_DATA := (\S+)$", text, re.MULTILINE).group(1)
    recipe = re.search(r"^walk:.*\n((?:\t.*\n)+)", text, re.MULTILINE).group(1)
    lines = [" ".join(line.split()) for line in recipe.splitlines() if not line.strip().startswith("mkdir")]
    return data, [line.replace("$(SC)", "$S").replace("$(WALK_DATA)", "$D") for line in lines]


def test_the_readme_is_at_most_200_lines_and_maps_every_doc():
    text = README.read_text()
    assert len(text.splitlines()) <= 200, f"README.md has {len(text.splitlines())} lines"
    unmapped = [p.name for p in sorted((ROOT / "docs").glob("*.md"))
                if f"(docs/{p.name})" not in text and f"`{p.name}`" not in text]
    assert unmapped == [], f"README.md's map of docs/ does not name {unmapped}"


def test_the_readme_walk_is_what_make_walk_runs():
    data, recipe = makefile_walk()
    block = next(b for b in bash_blocks(README.read_text()) if "D=examples/" in b)
    assert f"D={data}" in block.splitlines()[0]
    assert commands(block) == recipe


def test_benchmarks_md_names_every_script_with_options_it_takes():
    text = BENCHMARKS.read_text()
    scripts = sorted(p.name for p in (ROOT / "benchmarks").glob("bench_*.py"))
    assert [s for s in scripts if s not in text] == [], "docs/benchmarks.md leaves these scripts out"
    runs = SCRIPT_RUN.findall(text)
    assert len([r for r in runs if r[1]]) >= 10            # the commands are written with their options
    for name, options in runs:
        assert name in scripts, f"docs/benchmarks.md runs {name}, which benchmarks/ does not hold"
        source = (ROOT / "benchmarks" / name).read_text()
        for option in re.findall(r"--[\w-]+", options):
            assert f'"{option}"' in source, f"docs/benchmarks.md runs {name} {option}, an option it does not take"
