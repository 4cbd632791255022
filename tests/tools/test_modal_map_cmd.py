"""`stiffcomp modal-map MEASURED.csv`: modes measured at six poses of an arm whose springs, arm and tool differ
from the prior by known factors give back that arm's modes at poses it was not measured at (``--at``, ``-o``),
from a service config (its model and the tool its gravity section carries) or a model and ``--tool-kg``;
bad input is refused, exit 2, without a traceback, naming the option, the file or the line."""

from __future__ import annotations

import json

import numpy as np
import pytest

from stiffness.dynamics.modal_map import JOINTS, ArmInertia, Factors, ModalMap
from stiffness.kinematics.robot import load_robot
from stiffness.kinematics.statics import PayloadConfig
from stiffness.model.cartesian import tcp_compliance
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import ROOT
from tools.cli import main

MASSES = str(ROOT / "config/robots/kr125_masses.yaml")
SERVICE = str(ROOT / "config/hil/service.yaml")                  # its model kr125_6dof, its tool 12 kg at 110 mm
TRUE = Factors(stiffness=0.95, arm=1.1, tool_kg=18.0)
CENTRE = np.array([0.0, -60.0, 90.0, 0.0, 60.0, 0.0])


@pytest.fixture(scope="module")
def arm():
    model = StiffnessModel.from_yaml(ROOT / "config/models/kr125_6dof.yaml")
    tool = PayloadConfig(mass_kg=12.0, cog_mm=[0.0, 0.0, 110.0])
    return ModalMap(lambda q: tcp_compliance(model, q), ArmInertia(load_robot(MASSES), tool))


def write(path, poses, hz=None):
    head = list(JOINTS) + ([f"f{k + 1}_hz" for k in range(hz.shape[1])] if hz is not None else [])
    rows = poses if hz is None else np.column_stack([poses, hz])
    path.write_text(",".join(head) + "\n" + "".join(",".join(f"{x:.6f}" for x in r) + "\n" for r in rows))
    return path


def refused(argv, capsys) -> str:
    assert main(["modal-map", *argv]) == 2
    err = capsys.readouterr().err
    assert err.startswith("stiffcomp modal-map: error: ") and "Traceback" not in err, err
    return err


def test_six_measured_poses_give_the_arms_modes_where_it_was_not_measured(arm, tmp_path, capsys):
    rng = np.random.default_rng(5)
    poses = CENTRE + rng.uniform(-1, 1, (10, 6)) * [25, 12, 12, 10, 10, 10]
    measured = write(tmp_path / "measured.csv", poses[:6], arm.predict(poses[:6], TRUE)[0][:, :2])
    at, out = write(tmp_path / "at.csv", poses[6:]), tmp_path / "modes.csv"
    assert main(["modal-map", str(measured), "--config", SERVICE, "--masses", MASSES, "--at", str(at),
                 "-o", str(out), "--plot", str(tmp_path / "map.png"), "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert max(got["error_pct"]["prior"]["max_abs"]) > 3 and max(got["error_pct"]["map"]["max_abs"]) < 0.3
    table = np.genfromtxt(out, delimiter=",", names=True)
    true_hz = arm.predict(poses[6:], TRUE)[0]
    np.testing.assert_allclose(np.column_stack([table["f1_hz"], table["f2_hz"]]), true_hz[:, :2], rtol=0.003)
    np.testing.assert_allclose([r["hz"] for r in got["at"]], np.column_stack([table[f"f{k}_hz"] for k in (1, 2, 3)]),
                               rtol=1e-5)
    assert (tmp_path / "map.png").stat().st_size > 5_000


def test_a_model_and_its_tool_on_the_command_line_serve_alike(arm, tmp_path, capsys):
    poses = CENTRE + np.array([[0, 0, 0, 0, 0, 0], [20, 10, -10, 0, 0, 0], [-20, -8, 12, 0, 0, 0]])
    measured = write(tmp_path / "measured.csv", poses, arm.predict(poses, TRUE)[0][:, :1])
    assert main(["modal-map", str(measured), "--model", str(ROOT / "config/models/kr125_6dof.yaml"),
                 "--masses", MASSES, "--tool-kg", "12", "--tool-cog-mm", "0", "0", "110", "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["factors"]["tool_kg_prior"] == 12.0 and max(got["error_pct"]["map"]["max_abs"]) < 0.3


def test_bad_input_is_refused_naming_where(tmp_path, capsys):
    good = write(tmp_path / "m.csv", CENTRE[None], np.array([[10.0, 11.0]]))
    assert "--tool-kg and --tool-cog-mm go with --model" in refused(
        [str(good), "--config", SERVICE, "--tool-kg", "3"], capsys)
    assert "no link masses" in refused([str(good), "--config", SERVICE], capsys)      # kr125.yaml has none
    assert "give --at POSES.csv" in refused([str(good), "--config", SERVICE, "--masses", MASSES, "-o",
                                             str(tmp_path / "modes.csv")], capsys)
    assert not (tmp_path / "modes.csv").exists()
    assert "--plot map.bad: the suffix says the image's format" in refused(
        [str(good), "--config", SERVICE, "--masses", MASSES, "--plot", "map.bad"], capsys)
    bad = tmp_path / "bad.csv"
    bad.write_text(",".join(JOINTS) + ",f1_hz\n0,-60,90,0,60,zero,10\n")
    assert "line 2: q6_deg = 'zero' is not a number" in refused([str(bad), "--config", SERVICE, "--masses", MASSES],
                                                                capsys)
    assert "--tool-kg -1: the tool's mass" in refused(
        [str(good), "--model", str(ROOT / "config/models/kr125_6dof.yaml"), "--masses", MASSES, "--tool-kg", "-1"],
        capsys)
