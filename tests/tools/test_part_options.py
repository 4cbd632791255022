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


PROBE = "# stylus_radius_mm: 1.5\ntouch,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,approach_x,approach_y,approach_z\n"
TRACE = "time_s,cycle,q1_deg,q2_deg,q3_deg,q4_deg,q5_deg,q6_deg,fx_N\n0,1,0,-60,90,0,60,0,0\n"
CMM = "# tool_radius_mm: 4\npoint,x_mm,y_mm,z_mm\n1,1,2,3\n"


@pytest.mark.parametrize("order, message", [
    (("model.yaml", "probe.csv", "trace.csv"), "probe.csv: given as the trace, but it is a probe log (swapped with"),
    (("model.yaml", "part.csv", "trace.csv"), "part.csv: given as the trace, but it is a part (swapped with"),
    (("model.yaml", "trace.csv", "model.yaml"), "model.yaml: given as the part, but it is a YAML file (a model?)"),
    (("trace.csv", "model.yaml", "part.csv"), "trace.csv: given as the model, but a model is a YAML file"),
], ids=["probe-as-trace", "part-as-trace", "model-as-part", "trace-as-model"])
def test_swapped_arguments_are_called_swapped_before_anything_is_read_as_what_it_is_not(tmp_path, capsys, order,
                                                                                         message):
    for name, text in (("model.yaml", "robot: x\n"), ("probe.csv", PROBE), ("trace.csv", TRACE), ("part.csv", CMM)):
        (tmp_path / name).write_text(text)
    assert main(["part", "compare", *(str(tmp_path / f) for f in order)]) == 2
    err = capsys.readouterr().err
    assert message in err and "the order is MODEL TRACE PART" in err, err


def test_the_same_part_given_twice_is_refused(tmp_path, capsys):
    for name, text in (("model.yaml", "robot: x\n"), ("trace.csv", TRACE), ("part.csv", CMM)):
        (tmp_path / name).write_text(text)
    args = [str(tmp_path / "model.yaml"), str(tmp_path / "trace.csv"), str(tmp_path / "part.csv")]
    assert main(["part", "learn", *args, "--part", args[1], str(tmp_path / "." / "part.csv"), "-o",
                 str(tmp_path / "x.yaml")]) == 2
    assert "part.csv: the same part is given twice" in capsys.readouterr().err
