"""docs/part.md's examples are what the commands print (issue 35, item 14).

Every code block of the page that opens with a `$ stiffcomp ...` line is run, in the page's order, in a folder
of its own that holds examples/ and config/ as a checkout does (and the truth_h.yaml and truth_gh.yaml the page
describes, made as it says), in lock step, so the figures are the same on every run. What each prints is held to the page's
lines: the same words, every number within two units of its last printed digit (an integer exactly), and
`...` standing for lines (a line of its own) or for text within a line left out.
"""

from __future__ import annotations

import re
import shlex

from stiffness.model.stiffness_model import StiffnessModel
from testlib.hil import ROOT
from tools.cli import main

PAGE = ROOT / "docs" / "part.md"
NUMBER = r"[-+]?\d+(?:\.\d+)?(?:e[-+]?\d+)?"
TOKEN = re.compile(rf"(\.\.\.|{NUMBER})")


def examples() -> list[tuple[str, list[str]]]:
    """(command, the lines the page shows it print) for each block that opens with '$ stiffcomp '."""
    blocks: list[list[str]] = []
    inside = False
    for line in PAGE.read_text().splitlines():
        if line.startswith("```"):
            inside = not inside
            if inside:
                blocks.append([])
        elif inside:
            blocks[-1].append(line)
    return [(b[0][2:], b[1:]) for b in blocks if b and b[0].startswith("$ stiffcomp ")]


def numbers_close(shown: str, printed: str) -> bool:
    """A number as the page shows it and as the command printed it: within two units of the shown number's
    last digit; an integer exactly."""
    mantissa, _, exponent = shown.lower().partition("e")
    if "." not in mantissa and not exponent:
        return int(shown) == int(float(printed))
    decimals = len(mantissa.partition(".")[2])
    return abs(float(shown) - float(printed)) <= 2.0 * 10.0 ** (int(exponent or 0) - decimals) * (1 + 1e-9)


def line_matches(shown: str, printed: str) -> bool:
    """Whether ``printed`` is the line the page shows: its words, its numbers (`numbers_close`), '...' for
    any text. False when the words differ; AssertionError when only the numbers do."""
    pieces = TOKEN.split(shown)
    pattern = "".join(".*?" if p == "..." else f"({NUMBER})" if k % 2 else re.escape(p)
                      for k, p in enumerate(pieces))
    m = re.fullmatch(pattern, printed)
    if not m:
        return False
    wanted = [p for k, p in enumerate(pieces) if k % 2 and p != "..."]
    off = [(w, g) for w, g in zip(wanted, m.groups()) if not numbers_close(w, g)]
    assert not off, f"docs/part.md shows {off[0][0]} where the command prints {off[0][1]}:\n  {shown}\n  {printed}"
    return True


def assert_prints(shown: list[str], printed: list[str], command: str) -> None:
    i, skipping = 0, False
    for line in shown:
        if line.strip() == "...":
            skipping = True
            continue
        while True:
            assert i < len(printed), f"`{command}` did not print: {line}"
            i += 1
            if line_matches(line, printed[i - 1]):
                break
            assert skipping, f"`{command}`: docs/part.md shows\n  {line}\nwhere it prints\n  {printed[i - 1]}"
        skipping = False
    assert skipping or i == len(printed), f"`{command}` printed more than the page shows: {printed[i:]}"


def test_the_pages_examples_are_what_the_commands_print(tmp_path, monkeypatch, capsys):
    found = examples()
    commands = [c for c, _ in found]
    assert any(" part compare " in c for c in commands) and any(" part learn " in c for c in commands)
    assert any(" part diagnose " in c for c in commands) and all("--lockstep" in c for c in commands
                                                                 if " hil circle " in c)
    for name in ("examples", "config"):
        (tmp_path / name).symlink_to(ROOT / name)
    truth = StiffnessModel.from_yaml(ROOT / "examples" / "truth_reference.yaml")
    d = truth.to_dict()
    d["effects"].append({"effect": "hysteresis", "joint": 1, "offset_deg": 0.012})
    StiffnessModel.from_dict(d, "truth_h", robot=truth.robot).to_yaml(tmp_path / "truth_h.yaml")
    built = StiffnessModel.from_yaml(ROOT / "examples" / "truth_geometric_errors.yaml")       # the same hysteresis on
    d = built.to_dict()                                                                      # the robot with DH errors
    d["effects"].append({"effect": "hysteresis", "joint": 1, "offset_deg": 0.012})
    StiffnessModel.from_dict(d, "truth_gh", robot=built.robot).to_yaml(tmp_path / "truth_gh.yaml")
    monkeypatch.chdir(tmp_path)
    for command, shown in found:
        argv = shlex.split(command)
        assert argv[0] == "stiffcomp"
        rc = main(argv[1:])
        out, err = capsys.readouterr()
        assert rc == 0, f"`{command}` exited {rc}: {err[-2000:]}"
        assert_prints(shown, out.splitlines(), command)
