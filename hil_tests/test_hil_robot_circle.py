"""`stiffcomp hil circle --robot-interface`: what it refuses before any process starts (the circle itself through
each road, its summary and the part loop: hil_tests/test_hil_part_road.py). There is no lock step on the robot's
clock, and EGM's joint mode, which follows no path, cannot cut the circle: each refused in one line."""

from __future__ import annotations

from tools.cli import main


def test_the_robot_road_has_no_lock_step(capsys, tmp_path):
    assert main(["hil", "circle", "--lockstep", "--robot-interface", "abb_egm", "--report", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "the robot road runs on the robot's clock, in real time only" in err, err
    assert list(tmp_path.iterdir()) == []


def test_egm_joint_mode_cannot_cut_the_circle(capsys, tmp_path):
    cfg = tmp_path / "joint.yaml"
    cfg.write_text("robot:\n  abb_egm: {mode: joint}\n")
    assert main(["hil", "circle", "--robot-interface", "abb_egm", "--robot-config", str(cfg),
                 "--report", str(tmp_path / "r")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "position guidance, which runs no RAPID path" in err, err
    assert not (tmp_path / "r").exists()
