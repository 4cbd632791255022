"""`stiffcomp fit` end to end, as a user runs it (`tools.cli.main`, in this process); bad inputs exit 2 with a clear message."""

import json

import pytest
import yaml

from testlib.common import DATA, MODELS, ROOT, run_cli

pytestmark = pytest.mark.slow


def stiffcomp(*args, cwd=ROOT):
    return run_cli(*args, cwd=cwd)


def test_fit_json_meets_reference(tmp_path):
    out = tmp_path / "fitted.yaml"
    r = stiffcomp("fit", MODELS / "kr125_6dof.yaml", DATA / "reference_campaign.csv", "-o", out, "--json")
    assert r.returncode == 0, r.stderr
    res = json.loads(r.stdout)
    truth = yaml.safe_load((DATA / "reference_truth.yaml").read_text())
    assert res["rms_position_mm"] == pytest.approx(truth["noise_sigma"]["position_mm"], rel=0.1)
    assert res["rms_rotation_deg"] == pytest.approx(truth["noise_sigma"]["rotation_deg"], rel=0.1)
    assert [j["joint"] for j in res["joint_stiffness"]] == [1, 2, 3, 4, 5, 6]
    for j, tr in zip(res["joint_stiffness"], truth["springs"]["compliance"]):
        assert set(j) == {"joint", "x", "y", "z", "rx", "ry", "rz"}
        assert j["rz"] == pytest.approx(tr["axial_stiffness_Nm_per_rad"], rel=0.03)
        assert j["rx"] == pytest.approx(1 / tr["rx_rad_per_Nm"], rel=0.25)
    assert "cannot be told from zero" in r.stderr
    # the fitted model loads again and predicts as well as it fitted
    r2 = stiffcomp("fit", out, DATA / "reference_campaign.csv", "--json")
    assert json.loads(r2.stdout)["rms_position_mm"] == pytest.approx(res["rms_position_mm"], rel=1e-3)


def test_axial_model_reports_null_for_absent_components():
    r = stiffcomp("fit", MODELS / "kr125_axial.yaml", DATA / "reference_campaign.csv", "--json")
    res = json.loads(r.stdout)
    for j in res["joint_stiffness"]:
        assert j["x"] is None and j["rx"] is None and j["rz"] > 0


@pytest.mark.parametrize("text, expected", [
    ("name: m\nrobot: ../robots/kr125.yaml\neffects: [{effect: springz, joint: 1}]\n",
     "effect = 'springz' is not in the library"),
    ("name: m\nrobot: ../robots/kr125.yaml\neffects: [{effect: joint_spring, joint: 7, rz_rad_per_Nm: 1e-7}]\n",
     "joint = 7 must be one of 1, 2, 3, 4, 5, 6"),
    ("name: m\nrobot: ../robots/kr125.yaml\neffects: [{effect: joint_spring, joint: 1, rz_rad_per_nm: 1e-7}]\n",
     "rz_rad_per_nm is not a key of effect 'joint_spring'"),
    ("name: m\nrobot: ../robots/kr125.yaml\neffects: [{effect: joint_spring, joint: 1, rz_rad_per_Nm: abc}]\n",
     "rz_rad_per_Nm = 'abc' is not a number"),
    ("name: m\nrobot: nowhere.yaml\neffects: [{effect: joint_spring, joint: 1}]\n", "nowhere.yaml"),
    ("name: m\nrobot: ../robots/kr125.yaml\ncolour: red\neffects: []\n", "colour is not a known key"),
    ("name: [unclosed\n", "is not valid YAML"),
])
def test_bad_model_files_exit_2_naming_file_and_key(tmp_path, text, expected):
    (tmp_path / "models").mkdir()
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "kr125.yaml").write_text((ROOT / "config/robots/kr125.yaml").read_text())
    bad = tmp_path / "models" / "bad.yaml"
    bad.write_text(text)
    r = stiffcomp("fit", bad, DATA / "reference_campaign.csv")
    assert r.returncode == 2
    assert "bad.yaml" in r.stderr and expected in r.stderr
    assert "Traceback" not in r.stderr


def test_bad_data_file_exits_2(tmp_path):
    bad = tmp_path / "d.csv"
    bad.write_text("time_s,config\n1,R1\n")
    r = stiffcomp("fit", MODELS / "kr125_6dof.yaml", bad)
    assert r.returncode == 2 and "missing column" in r.stderr and "Traceback" not in r.stderr


def test_outputs_go_into_new_folders_and_unwritable_ones_exit_2(tmp_path):
    out = tmp_path / "new" / "folder" / "fitted.yaml"
    r = stiffcomp("fit", MODELS / "kr125_axial.yaml", DATA / "reference_campaign.csv", "-o", out)
    assert r.returncode == 0 and out.exists()
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    r = stiffcomp("model", "add", out, "backlash", "--joint", "3", "-o", blocker / "m.yaml")
    assert r.returncode == 2 and "cannot write" in r.stderr and "Traceback" not in r.stderr
