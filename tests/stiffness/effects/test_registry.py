"""Each effect owns itself (issue 18): its module holds everything about it, and the registry is the only
place outside `stiffness/effects/` that knows the effects, never by their names written as strings.
"""

from __future__ import annotations

import ast
import doctest
import importlib
import re
from pathlib import Path

import pytest

from stiffness.effects import EFFECTS, Effect
from stiffness.effects.base import EVIDENCE_PLOTS

ROOT = Path(__file__).resolve().parents[3]
SOURCE_FOLDERS = ("stiffness", "service", "io_process", "robot_road", "plc_link", "io_base", "tools", "hil", "benchmarks")
MODULES = sorted({cls.__module__ for cls in EFFECTS.values()})


def string_literals(path: Path):
    """(line, text) of every string constant in a Python file, f-string parts included, docstrings not."""
    tree = ast.parse(path.read_text(), str(path))
    docstrings = {id(node.body[0].value) for node in ast.walk(tree)
                  if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef))
                  and node.body and isinstance(node.body[0], ast.Expr)
                  and isinstance(node.body[0].value, ast.Constant)}
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, str) and id(node) not in docstrings:
            yield node.lineno, node.value


def named_effects(path: Path) -> list[tuple[int, str]]:
    """The string literals of ``path`` that hold an effect's name as a word."""
    return sorted((line, text) for line, text in string_literals(path)
                  if set(EFFECTS) & set(re.findall(r"\w+", text)))


def test_no_effect_is_named_by_string_outside_its_own_module():
    found = [f"{path.relative_to(ROOT)}:{line}: {text[:60]!r}"
             for folder in SOURCE_FOLDERS for path in sorted((ROOT / folder).rglob("*.py"))
             if not path.is_relative_to(ROOT / "stiffness" / "effects")
             for line, text in named_effects(path)]
    assert not found, "effect names written as strings outside stiffness/effects/:\n" + "\n".join(found)


def test_the_check_sees_a_name_written_as_a_string(tmp_path):
    """The scan above is not blind: a dispatch on a name, or an entry naming one, is found."""
    bad = tmp_path / "bad.py"
    bad.write_text('"""A docstring that says backlash is fine."""\n'
                   'if e.name == "backlash":\n    pass\nENTRY = {"effect": "hysteresis", "joint": 2}\n')
    assert named_effects(bad) == [(2, "backlash"), (4, "hysteresis")]


@pytest.mark.parametrize("name", sorted(EFFECTS))
def test_each_effect_declares_what_the_other_floors_ask_of_it(name):
    cls = EFFECTS[name]
    assert cls.evidence_plot in EVIDENCE_PLOTS
    assert cls.equation
    for entry in cls.examples:            # its examples are valid model entries of its own
        assert entry["effect"] == name
        cls.from_config(entry, None, f"{name}.examples")
    assert issubclass(cls, Effect)


@pytest.mark.parametrize("module", MODULES)
def test_each_effect_module_runs_its_example(module):
    mod = importlib.import_module(module)
    result = doctest.testmod(mod, optionflags=doctest.ELLIPSIS)
    assert result.attempted > 0, f"{module} has no runnable example in its docstrings"
    assert result.failed == 0
