"""`stiffcomp part compare | learn | diagnose` take the robot's own probe log as they take a CMM's points
(issue 46); a part frame or a best fit given with one is refused as meaningless, one line, exit 2."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from stiffness.data.probe_log import write_probe
from stiffness.kinematics.robot import PoseConfig
from stiffness.model.stiffness_model import StiffnessModel
from testlib.part import STYLUS_RADIUS_MM, TOOL_RADIUS_MM, probe_touches, synthetic_cut
from tools.cli import main

ROOT = Path(__file__).resolve().parents[2]
MODEL = ROOT / "examples" / "truth_reference.yaml"
BUILT = ROOT / "examples" / "truth_geometric_errors.yaml"


@pytest.fixture(scope="module")
def probed(tmp_path_factory):
    folder = tmp_path_factory.mktemp("probe_cli")
    truth = StiffnessModel.from_yaml(BUILT)
    cut = synthetic_cut(truth, folder, points=90, noise_um=0.0)
    q, n, _ = probe_touches(cut, truth.robot, touches=30)
    log = write_probe(folder / "probe.csv", q, n, TOOL_RADIUS_MM, STYLUS_RADIUS_MM, PoseConfig(xyz_mm=[0, 0, 250]))
    return cut, log


def test_compare_reads_a_probe_log_in_the_robots_base(probed, capsys):
    cut, log = probed
    assert main(["part", "compare", str(MODEL), str(cut.trace), str(log), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["points"] == 30
    # the exact springs on the datasheet's kinematics explain the robot-as-built's touches to a few um
    assert out["model_missed_rms_mm"] < 0.01, out["model_missed_rms_mm"]


@pytest.mark.parametrize("action", ["compare", "learn", "diagnose"])
@pytest.mark.parametrize("option", [["--part-frame", "1800", "0", "800", "0", "0", "0"], ["--best-fit"]])
def test_a_part_frame_or_a_best_fit_with_a_probe_log_is_refused(probed, tmp_path, capsys, action, option):
    cut, log = probed
    extra = ["-o", str(tmp_path / "learned.yaml")] if action == "learn" else []
    assert main(["part", action, str(MODEL), str(cut.trace), str(log), *option, *extra]) == 2
    out, err = capsys.readouterr()
    lines = err.strip().splitlines()
    assert len(lines) == 1 and not out and "Traceback" not in err, err
    assert f"{option[0]} is meaningless with the probe log {log}" in lines[0]
    assert "a probe log needs no part frame" in lines[0]
    assert list(tmp_path.iterdir()) == []
