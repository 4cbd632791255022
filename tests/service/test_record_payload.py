"""`stiffcomp record` makes a log the replay source reads; `stiffcomp payload` recovers a known payload."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest

from hil.testing import model_with, write_config
from service.ati import AtiProtocol
from service.config import load_config
from service.gravity import GravityCompensator
from service.sources.replay import ReplaySource, read_log
from stiffness.kinematics.spatial import exp_so3
from stiffness.model.stiffness_model import StiffnessModel
from tools.cli import main


@pytest.mark.parametrize("suffix", [".asc", ".blf"])
def test_record_from_the_virtual_sensor_then_replay(tmp_path, suffix, capsys):
    cfg = write_config(tmp_path, {"source": {"can": {"channel": f"rec{suffix[1:]}"}}})
    out = tmp_path / f"rec{suffix}"
    assert main(["record", str(out), "--config", str(cfg), "--virtual-sensor", "--duration", "0.5"]) == 0
    printed = capsys.readouterr().out
    assert "requests sent" in printed and "samples decoded with" in printed and "Fz: min" in printed
    frames = read_log(out)
    src = ReplaySource(frames, pacing="fast", loop=False, protocol=AtiProtocol(), timeout_s=1.0,
                       max_force_N=2500.0, max_torque_Nm=250.0)
    readings, k = [], 0
    while not src.exhausted:
        r, errors = src.poll(k * 1e-3)
        k += 1
        assert errors == [], errors
        if r is not None:
            readings.append(r.wrench)
    assert len(readings) >= 5, len(readings)          # a loaded machine answers fewer of the requests
    assert np.abs(np.array(readings)).max() < 2500


def test_a_sensor_that_never_answers_is_named_not_recorded_in_silence(tmp_path, capsys):
    """Issue 45, item 9: no sensor on the bus (a wrong channel) wrote a log of requests alone and exited 0; the
    reference of the idle sensor then held none of it. Exit 1, one line naming what to check."""
    cfg = write_config(tmp_path, {"source": {"can": {"channel": "rec_nobody"}}})
    out = tmp_path / "idle.blf"
    assert main(["record", str(out), "--config", str(cfg), "--duration", "0.2"]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith(f"record: no sensor sample in {out}: nothing answered"), err
    assert "source.can.interface, channel and source.ati.base_id" in err[0]


def test_record_refuses_an_unknown_log_type(tmp_path, capsys):
    assert main(["record", str(tmp_path / "x.mp3"), "--duration", "0.1"]) == 2
    assert "must be one of" in capsys.readouterr().err


def synthetic_poses(path, mass, cog_m, bias, n=10, seed=0, turned_deg=(0.0, 0.0, 0.0)):
    """Static poses of a payload; the sensor's real axes turned by ``turned_deg`` (a rotation vector)
    against the robot file's."""
    cfg = load_config()
    robot = StiffnessModel.from_yaml(cfg.resolve(cfg.model.file)).robot
    gc = GravityCompensator(mass, cog_m, bias, np.array(cfg.gravity.g_mps2))
    rng = np.random.default_rng(seed)
    lim = robot.limits_deg
    q = rng.uniform(lim[:, 0] * 0.8, lim[:, 1] * 0.8, size=(n, 6))
    R = robot.sensor_pose(robot.frames(np.radians(q)))[:, :3, :3] @ exp_so3(np.radians(turned_deg))
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([f"q{i}_deg" for i in range(1, 7)] + ["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"])
        for k in range(n):
            w.writerow(list(q[k]) + list(np.array(gc.payload_wrench(R[k])) + bias + rng.normal(0, 0.02, 6)))


def test_payload_recovers_mass_cog_and_bias(tmp_path, capsys):
    bias = np.array([5.0, -3.0, 8.0, 0.3, -0.2, 0.1])
    synthetic_poses(tmp_path / "poses.csv", 11.0, [0.005, -0.01, 0.12], bias)
    assert main(["payload", str(tmp_path / "poses.csv"), "--json"]) == 0
    r = json.loads(capsys.readouterr().out)
    assert r["ok"] and abs(r["mass_kg"] - 11.0) < 0.02
    np.testing.assert_allclose(r["cog_mm"], [5.0, -10.0, 120.0], atol=1.0)
    np.testing.assert_allclose(r["bias"], bias, atol=0.05)
    assert main(["payload", str(tmp_path / "poses.csv")]) == 0
    assert "gravity:" in capsys.readouterr().out


def test_payload_takes_the_sensor_misalignment_of_the_model(tmp_path, capsys):
    """A sensor turned by 3 degrees: with the misalignment in the config's model, the payload comes back
    in the sensor's real axes (where the service compensates it); without it, the fit is visibly worse."""
    bias = np.array([5.0, -3.0, 8.0, 0.3, -0.2, 0.1])
    synthetic_poses(tmp_path / "poses.csv", 11.0, [0.005, -0.01, 0.12], bias, turned_deg=(0.0, 0.0, 3.0))
    cfg = load_config()
    model_with({"effect": "sensor_misalignment", "rz_deg": 3.0}, base=cfg.resolve(cfg.model.file)).to_yaml(
        tmp_path / "model.yaml")
    results = {}
    for name, model in (("aligned", cfg.resolve(cfg.model.file)), ("turned", tmp_path / "model.yaml")):
        (tmp_path / name).mkdir()
        path = write_config(tmp_path / name, {"model": {"file": str(model)}})
        assert main(["payload", str(tmp_path / "poses.csv"), "--config", str(path), "--json"]) == 0
        results[name] = json.loads(capsys.readouterr().out)
    r = results["turned"]
    assert abs(r["mass_kg"] - 11.0) < 0.02
    np.testing.assert_allclose(r["cog_mm"], [5.0, -10.0, 120.0], atol=1.0)
    np.testing.assert_allclose(r["bias"], bias, atol=0.05)
    assert max(results["aligned"]["residual_rms"][:3]) > 10 * max(r["residual_rms"][:3])


def test_payload_with_bad_file_is_a_user_error(tmp_path, capsys):
    (tmp_path / "p.csv").write_text("q1_deg,fx_N\n1,2\n")
    assert main(["payload", str(tmp_path / "p.csv")]) == 2
    assert "missing column(s)" in capsys.readouterr().err
