"""`stiffcomp torques` and the static torques `stiffcomp kcart` prints, run as a user runs them."""

import json

import numpy as np
import pytest

from stiffness.kinematics.statics import Statics
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import MODELS, ROOT
from testlib.common import run_cli as stiffcomp
from tools.cli import main

Q = [10.0, -80.0, 95.0, 20.0, 50.0, -30.0]


@pytest.fixture(scope="module")
def MODEL(tmp_path_factory):
    """kr125_6dof on the KR 125 with its masses (config/robots/kr125_masses.yaml)."""
    model = StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml")
    data = model.to_dict() | {"robot": str(ROOT / "config" / "robots" / "kr125_masses.yaml")}
    path = tmp_path_factory.mktemp("torques") / "kr125_6dof_masses.yaml"
    StiffnessModel.from_dict(data, str(path)).to_yaml(path)
    return path




def test_torques_json_equals_statics_and_sums(MODEL):
    r = stiffcomp("torques", MODEL, "--q", *Q, "--payload-kg", 80, "--payload-cog-mm", 0, 10, 150, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)["static_torque_Nm"]
    robot = StiffnessModel.from_yaml(MODEL).robot
    expected = Statics(robot, 80.0, (0, 10, 150))(np.radians(Q))
    for part in ("arm", "payload", "balancer", "total"):
        np.testing.assert_allclose(out[part], getattr(expected, part)[0], rtol=1e-12, atol=1e-9)
    np.testing.assert_allclose(out["total"], np.sum([out[p] for p in ("arm", "payload", "balancer")], axis=0))
    assert abs(out["arm"][1]) > 100 and abs(out["payload"][1]) > 100 and out["balancer"][1] != 0


def test_torques_table_has_a_line_per_joint_with_the_parts_that_add_up(MODEL):
    r = stiffcomp("torques", MODEL, "--q", *Q, "--payload-kg", 50)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    head = next(k for k, line in enumerate(lines) if line.split()[:5] == ["joint", "arm", "payload", "balancer", "total"])
    rows = [line.split() for line in lines[head + 1:head + 7]]
    assert [row[0] for row in rows] == [f"A{i}" for i in range(1, 7)]
    values = np.array([[float(v) for v in row[1:]] for row in rows])
    np.testing.assert_allclose(values[:, :3].sum(1), values[:, 3], atol=0.11)     # printed to 0.1 Nm
    assert "50 kg" in r.stdout and "balancer on joint 2" in r.stdout


def test_kcart_prints_the_static_torques_of_its_configuration(MODEL):
    r = stiffcomp("kcart", MODEL, "--q", *Q, "--json")
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout)["model"]["static_torque_Nm"]
    robot = StiffnessModel.from_yaml(MODEL).robot
    np.testing.assert_allclose(out["total"], Statics(robot)(np.radians(Q)).total[0], rtol=1e-12, atol=1e-9)
    text = stiffcomp("kcart", MODEL, "--q", *Q).stdout
    assert "static joint torques" in text and "A6" in text


def test_bad_options_exit_2_naming_the_option(MODEL):
    r = stiffcomp("torques", MODEL, "--q", 0, 40, 0, 0, 0, 0)
    assert r.returncode == 2 and "--q: joint 2 = 40 deg is outside its limits [-155, 35]" in r.stderr
    r = stiffcomp("torques", MODEL, "--q", *Q, "--payload-kg", "-2")
    assert r.returncode == 2 and "payload mass = -2.0 kg must be a finite number >= 0" in r.stderr
    assert "Traceback" not in r.stderr


# -- issue 27, item 2: `torques` shows what fit and the service use ------------------------------------------

UPRIGHT = [0.0, -90.0, 90.0, 0.0, 90.0, 0.0]
PAYLOAD = ["--payload-kg", "12", "--payload-cog-mm", "0", "0", "110"]


def service_tau_s(model_path, q_deg, kg: float, cog_mm) -> np.ndarray:
    """tau_s as the service's predictor forms it with this payload carried (`FastPredictor.carry`)."""
    from service.compensation import FastPredictor

    fp = FastPredictor(StiffnessModel.from_yaml(model_path))
    fp.carry(kg, np.asarray(cog_mm) / 1000.0, [0.0, 0.0, -9.81])
    fp.kinematics(np.radians(q_deg))
    return np.array(fp.tau_s)


def test_a_robot_without_masses_says_the_payload_is_not_modelled_instead_of_a_torque(capsys):
    """kr125_6dof's robot has no masses: fit and the service take tau_s = 0, the payload's included. The
    table used to print 117.7 Nm of payload torque at joints 2 and 3 that nothing used."""
    model = MODELS / "kr125_6dof.yaml"
    assert main(["torques", str(model), "--q", *map(str, UPRIGHT), *PAYLOAD]) == 0
    out = capsys.readouterr().out
    assert "117.7" not in out and not any(line.startswith(("joint ", "A2")) for line in out.splitlines())
    assert "no static load modelled" in out and "a payload (12 kg) is not modelled either" in out
    assert main(["torques", str(model), "--q", *map(str, UPRIGHT), *PAYLOAD, "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["modelled"] is False and "no static load modelled" in got["note"]
    np.testing.assert_array_equal(got["static_torque_Nm"]["total"], service_tau_s(model, UPRIGHT, 12.0, (0, 0, 110)))
    assert not np.any(got["static_torque_Nm"]["payload"])


def test_with_masses_the_total_is_what_the_service_forms(MODEL, capsys):
    assert main(["torques", str(MODEL), "--q", *map(str, Q), *PAYLOAD, "--json"]) == 0
    got = json.loads(capsys.readouterr().out)
    assert got["modelled"] is True
    np.testing.assert_allclose(got["static_torque_Nm"]["total"], service_tau_s(MODEL, Q, 12.0, (0, 0, 110)),
                               rtol=1e-12, atol=1e-9)
    assert abs(got["static_torque_Nm"]["payload"][1]) > 10
