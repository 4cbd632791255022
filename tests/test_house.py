"""The house's rules, read from the source: no module imports another that imports it back (at any depth,
function-level imports included), modules and functions stay a size a reader can hold, the science keeps
its rooms, and no code cites a guide the repository does not hold. `lint-imports` (run by `make test`)
holds the direction of the imports; this holds what a layers contract cannot see."""

from __future__ import annotations

import ast
import re
from pathlib import Path

from testlib.common import ROOT

PACKAGES = ("stiffness", "io_base", "plc_link", "robot_road", "io_process", "service", "tools", "hil", "cell",
            "st_runtime", "testlib")
MAX_MODULE_LINES = 400
MAX_FUNCTION_LINES = 80


def modules() -> dict[str, Path]:
    """Dotted name -> file, for every module of the packages."""
    out = {}
    for pkg in PACKAGES:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            parts = list(path.relative_to(ROOT).with_suffix("").parts)
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def imports(name: str, path: Path, known: set[str]) -> set[str]:
    """The project's modules ``name`` imports, anywhere in its file (a package's ``from . import x``
    resolved to the module x when it is one)."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        targets = []
        if isinstance(node, ast.Import):
            targets = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = package[:len(package) - node.level + 1] if node.level else []
            mod = ".".join(base + ([node.module] if node.module else []))
            targets = [mod] + [f"{mod}.{a.name}" for a in node.names]
        for t in targets:
            while t and t not in known:
                t = t.rpartition(".")[0]
            if t and t != name:
                found.add(t)
    return found


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_cycles_finds_a_circle_and_only_a_circle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_modules_import_each_other_in_a_circle():
    """An edge from a module to a package it lies in is left out: Python has that package imported before
    the module, whatever the module names (``from . import template`` imports the sibling, not the
    package again), so a registry's ``__init__`` and the modules it gathers are no circle."""
    mods = modules()
    known = set(mods)
    graph = {}
    for name, path in mods.items():
        deps = imports(name, path, known)
        graph[name] = {d for d in deps if not name.startswith(d + ".")}
    assert cycles(graph) == []


def test_no_module_over_400_lines_and_no_function_over_80():
    long_modules, long_functions = [], []
    for name, path in modules().items():
        text = path.read_text()
        if text.count("\n") > MAX_MODULE_LINES:
            long_modules.append((name, text.count("\n")))
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_FUNCTION_LINES:
                    long_functions.append((f"{name}.{node.name}", n))
    assert long_modules == [] and long_functions == []


def packed(tree: ast.AST) -> list[int]:
    """The lines where a statement starts beside another (``a; b``, ``if x: y``): a size limit met by packing is
    not met. A function whose whole body is ``...`` (a protocol's stub) is one statement."""
    starts: dict[int, int] = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.stmt):
            stub = (isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant)
                    and node.value.value is Ellipsis)
            if not stub:
                starts[node.lineno] = starts.get(node.lineno, 0) + 1
    return sorted(line for line, n in starts.items() if n > 1)


def test_packed_finds_packed_statements_and_only_those():
    assert packed(ast.parse("a = 1; b = 2\nif a:\n    b = 3\nif b: a = 4\n")) == [1, 4]
    assert packed(ast.parse("def f(self) -> int: ...\nx = [i for i in range(3)]\n")) == []


def test_no_statements_are_packed_onto_one_line():
    found = [f"{name}:{line}" for name, path in modules().items() if path.name != "egm_pb2.py"
             for line in packed(ast.parse(path.read_text()))]
    assert found == []


def test_the_science_keeps_its_rooms():
    """At most five modules flat in stiffness/, and at least six sub-packages."""
    flat = sorted(p.name for p in (ROOT / "stiffness").glob("*.py") if p.name != "__init__.py")
    rooms = sorted(p.name for p in (ROOT / "stiffness").iterdir() if (p / "__init__.py").exists())
    assert len(flat) <= 5, flat
    assert len(rooms) >= 6, rooms


def test_no_code_cites_a_guide_the_repository_does_not_hold():
    cited = re.compile(r"STYLE\.md|STYLE \d|guideline \d")
    files = [p for pkg in (*PACKAGES, "tests", "hil_tests", "benchmarks", "deploy") for p in (ROOT / pkg).rglob("*.py")]
    files += [ROOT / "Makefile", ROOT / "Dockerfile", ROOT / "pyproject.toml"]
    assert [str(p.relative_to(ROOT)) for p in files if cited.search(p.read_text())] == []
