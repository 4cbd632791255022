"""`stiffcomp part compare|learn|diagnose`: a bad option is refused before any work (issue 35, items 9 and 10):
one line on stderr naming the option, exit 2, nothing written. The model, trace and part named do not exist,
so a refusal that names the option came before anything was read."""

from __future__ import annotations

import pytest

from tools.cli import main

BAD_NUMBERS = [("--smooth-hz", "nan"), ("--smooth-hz", "-5"), ("--smooth-hz", "inf"), ("--near-mm", "-1"),
               ("--near-mm", "0"), ("--near-mm", "nan")]


def _inputs(folder) -> list[str]:
    return [str(folder / "absent_model.yaml"), str(folder / "absent_trace.csv"), str(folder / "absent_part.csv")]


def _refused(capsys, option: str) -> str:
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("stiffcomp part: error: ") and option in lines[0], err
    assert "absent_" not in lines[0] and "Traceback" not in err and not out
    return lines[0]


@pytest.mark.parametrize("action", ["compare", "learn", "diagnose"])
@pytest.mark.parametrize("option, value", BAD_NUMBERS)
def test_a_bad_number_is_refused_naming_the_option(tmp_path, capsys, action, option, value):
    extra = ["-o", str(tmp_path / "learned.yaml")] if action == "learn" else []
    assert main(["part", action, *_inputs(tmp_path), option, value, *extra]) == 2
    line = _refused(capsys, option)
    assert f"{option} {value}: must be a finite number" in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("action", ["learn", "diagnose"])
@pytest.mark.parametrize("value", ["0", "-0.5", "nan"])
def test_a_bad_prior_fraction_is_refused_naming_the_option(tmp_path, capsys, action, value):
    extra = ["-o", str(tmp_path / "learned.yaml")] if action == "learn" else []
    assert main(["part", action, *_inputs(tmp_path), "--prior-relative", value, *extra]) == 2
    _refused(capsys, "--prior-relative")


def test_learn_to_a_missing_folder_is_refused_and_creates_nothing(tmp_path, capsys):
    """As `stiffcomp modes -o` does: the folder must exist; nothing is created, not even the folder."""
    target = tmp_path / "no" / "such" / "folder" / "x.yaml"
    assert main(["part", "learn", *_inputs(tmp_path), "-o", str(target)]) == 2
    line = _refused(capsys, f"-o {target}")
    assert f"the folder {target.parent} does not exist" in line
    assert list(tmp_path.iterdir()) == []


def test_learn_to_a_folder_is_refused(tmp_path, capsys):
    assert main(["part", "learn", *_inputs(tmp_path), "-o", str(tmp_path)]) == 2
    assert "is a folder" in _refused(capsys, f"-o {tmp_path}")
