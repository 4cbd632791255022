"""Synthetic campaigns: determinism, the protocol's structure, recovery of the truth, clear errors."""

import numpy as np
import pytest
import yaml

from stiffness.data.measurements import read_measurements
from stiffness.errors import ConfigError
from stiffness.files.yaml_schema import dump_yaml
from stiffness.fit.identify import fit
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.plan.simulate import Campaign, simulate
from testlib.common import DATA, MODELS, ROOT
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"
EXAMPLE = ROOT / "examples" / "campaign_reference.yaml"
CONFIGS = [{"name": "R1", "q_deg": [10, -75, 90, 0, 75, 0]},
           {"name": "R2", "q_deg": [-25, -55, 65, 30, 80, -20]},
           {"name": "R3", "q_deg": [40, -85, 115, -60, 55, 45]}]


def write_campaign(tmp_path, name="c.yaml", **spec):
    body = {"truth": str(TRUTH), "configurations": CONFIGS, "seed": 5} | spec
    path = tmp_path / name
    path.write_text(dump_yaml(body))           # a configuration given twice is written out twice
    return path


def test_same_seed_same_campaign_other_seed_other_noise(tmp_path):
    path = write_campaign(tmp_path)
    a, b = simulate(path), simulate(path)
    np.testing.assert_array_equal(a.deflection, b.deflection)
    np.testing.assert_array_equal(a.wrench, b.wrench)
    other = Campaign.from_yaml(path)
    other.seed = 6
    c = other.run()
    assert not np.allclose(a.deflection, c.deflection)
    np.testing.assert_array_equal(a.q_deg, c.q_deg)


def test_protocol_structure(tmp_path):
    path = write_campaign(tmp_path, loads={"axes": ["x", "z"], "max_N": 900, "step_N": 300},
                          readings={"repeats": 2, "interval_s": 3, "settle_s": 5, "move_s": 60},
                          bodies=["A3", "TCP"])
    data = Campaign.from_yaml(path).run(noise=False)
    ramp = [0, 300, 600, 900, 600, 300, 0, -300, -600, -900, -600, -300, 0]
    n_read = len(CONFIGS) * 2 * len(ramp) * 2
    assert len(data) == n_read * 2
    assert data.configs == ["R1", "R2", "R3"]
    tcp = data.subset(data.body == 6)
    assert set(np.unique(data.body)) == {2, 6}
    # time runs in the order readings are taken, configurations one after the other
    assert np.all(np.diff(tcp.time_s) > 0)
    assert tcp.time_s[0] == 3.0 and tcp.time_s[1] - tcp.time_s[0] == 3.0
    assert tcp.time_s[2] - tcp.time_s[1] == 5.0 + 3.0
    for k, cfg in enumerate(data.configs):
        sub = tcp.subset(tcp.config == cfg)
        np.testing.assert_array_equal(sub.q_deg, np.tile(CONFIGS[k]["q_deg"], (len(sub), 1)))
        f = sub.wrench[:, :3]  # the sensor is the flange: the force is along the flange axis
        expected = np.zeros((len(ramp) * 2 * 2, 3))
        for a, axis in enumerate((0, 2)):
            expected[a * 2 * len(ramp):(a + 1) * 2 * len(ramp), axis] = np.repeat(ramp, 2)
        np.testing.assert_allclose(f, expected, atol=1e-9)
        # the moment about the sensor origin of a force at (100, 0, 250) mm
        np.testing.assert_allclose(sub.wrench[:, 3:], np.cross([0.1, 0.0, 0.25], f), atol=1e-9)
    gap = tcp.time_s[len(ramp) * 4] - tcp.time_s[len(ramp) * 4 - 1]
    assert gap == pytest.approx(5.0 + 60.0 + 3.0)


def test_example_reproduces_reference_campaign_structure(robot):
    ref = read_measurements(DATA / "reference_campaign.csv", robot)
    sim = simulate(EXAMPLE)
    assert len(sim) == len(ref) == 5355
    np.testing.assert_array_equal(sim.time_s, ref.time_s)
    np.testing.assert_array_equal(sim.config, ref.config)
    np.testing.assert_array_equal(sim.q_deg, ref.q_deg)
    np.testing.assert_array_equal(sim.body, ref.body)
    # the same loads up to the sensor noise (2 N, 0.5 Nm): well inside 6 sigma
    dw = np.abs(sim.wrench - ref.wrench)
    assert dw[:, :3].max() < 6 * 2.0 * np.sqrt(2) and dw[:, 3:].max() < 6 * 0.5 * np.sqrt(2)


def test_noise_has_the_promised_size_and_one_wrench_per_reading(tmp_path):
    path = write_campaign(tmp_path, noise={"position_mm": 0.05, "rotation_deg": 0.004,
                                           "force_N": 3.0, "moment_Nm": 0.2})
    c = Campaign.from_yaml(path)
    clean, noisy = c.run(noise=False), c.run()
    e = noisy.deflection - clean.deflection
    np.testing.assert_allclose(e[:, :3].std(), 0.05, rtol=0.05)
    np.testing.assert_allclose(e[:, 3:].std(), 0.004, rtol=0.05)
    w = noisy.wrench - clean.wrench
    np.testing.assert_allclose(w[:, :3].std(), 3.0, rtol=0.1)
    np.testing.assert_allclose(w[:, 3:].std(), 0.2, rtol=0.1)
    # all bodies of a reading carry the same measured wrench
    _, reading = noisy.readings()
    assert reading.max() + 1 == len(noisy) // 7


def test_unloaded_readings_have_no_deflection(tmp_path):
    data = Campaign.from_yaml(write_campaign(tmp_path)).run(noise=False)
    zero = np.abs(data.wrench).max(axis=1) == 0
    assert zero.sum() > 0
    assert np.abs(data.deflection[zero]).max() == 0.0
    assert np.abs(data.deflection[~zero]).max() > 0.1


def test_noise_free_campaign_fits_back_to_the_truth(tmp_path):
    """Recovery: the 36-parameter spring model fitted to a noise-free campaign gives the truth back."""
    path = write_campaign(tmp_path, configurations=CONFIGS + [
        {"name": "R4", "q_deg": [0, -50, 40, 0, 95, 90]}, {"name": "R5", "q_deg": [-40, -65, 95, 75, 65, -60]}],
        readings={"repeats": 1})
    c = Campaign.from_yaml(path)
    data = c.run(noise=False)
    start = StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml")
    result = fit(start, data)
    assert result.rms_position_mm < 1e-5 and result.rms_rotation_deg < 1e-7
    truth = c.truth.theta
    rot = np.array([lab.split(".")[-1].startswith("r") for lab in start.param_labels()])
    np.testing.assert_allclose(result.model.theta[rot], truth[rot], rtol=1e-3)
    np.testing.assert_allclose(result.model.theta[~rot], truth[~rot], rtol=0.05)


def test_time_dependent_truth_sees_the_readings_in_the_order_taken(tmp_path):
    """A drifting truth: unloaded readings move by v (t - t0) with t0 each configuration's first reading."""
    truth = yaml.safe_load(TRUTH.read_text())
    truth["robot"] = str(ROOT / "config" / "robots" / "kr125.yaml")
    truth["effects"].append({"effect": "drift", "x_mm_per_min": 0.05})
    (tmp_path / "drift.yaml").write_text(yaml.safe_dump(truth))
    data = Campaign.from_yaml(write_campaign(tmp_path, truth="drift.yaml", bodies=["TCP"],
                                             readings={"move_s": 300})).run(noise=False)
    unloaded = np.abs(data.wrench).max(axis=1) == 0
    for cfg in data.configs:
        rows = unloaded & (data.config == cfg)
        t0 = data.time_s[data.config == cfg].min()
        np.testing.assert_allclose(data.deflection[rows, 0], 0.05 * (data.time_s[rows] - t0) / 60, atol=1e-9)
        assert data.deflection[rows, 0].max() > 0.5


def test_random_configurations_inside_limits_and_reproducible(tmp_path, robot):
    path = write_campaign(tmp_path, configurations=[CONFIGS[0]],
                          random_configurations={"count": 12, "margin_deg": 10, "prefix": "Q"},
                          loads={"axes": ["y"]}, readings={"repeats": 1}, bodies=["TCP"])
    a, b = Campaign.from_yaml(path), Campaign.from_yaml(path)
    assert a.config_names[:2] == ["R1", "Q01"] and len(a.config_names) == 13
    np.testing.assert_array_equal(a.q_deg, b.q_deg)
    q = a.q_deg[1:]
    assert np.all(q >= robot.limits_deg[:, 0] + 10) and np.all(q <= robot.limits_deg[:, 1] - 10)
    assert len(np.unique(q[:, 0])) == 12
    assert len(a.run()) == 13 * 17


def test_cli_writes_the_measurement_format(tmp_path, robot, capsys):
    out = tmp_path / "sub" / "data.csv"
    path = write_campaign(tmp_path, readings={"repeats": 1})
    assert main(["simulate", str(path), "-o", str(out), "--seed", "3"]) == 0
    back = read_measurements(out, robot)
    direct = Campaign.from_yaml(path)
    direct.seed = 3
    data = direct.run()
    np.testing.assert_allclose(back.deflection, data.deflection, atol=1e-6)
    np.testing.assert_allclose(back.wrench, data.wrench, atol=1e-4)
    assert "wrote" in capsys.readouterr().out


@pytest.mark.parametrize("change, message", [
    ({"loads": {"max_n": 1200}}, r"loads\.max_n is not a known key"),
    ({"loads": {"max_N": -5}}, r"loads\.max_N = -5: .*greater than 0"),
    ({"loads": {"step_N": 2000}}, r"loads\.step_N = 2000 must not exceed loads\.max_N = 1200"),
    ({"loads": {"axes": ["x", "w"]}}, r"loads\.axes\.1 = 'w'"),
    ({"readings": {"repeats": 0}}, r"readings\.repeats = 0: .*greater than or equal to 1"),
    ({"noise": {"force_N": -1}}, r"noise\.force_N = -1"),
    ({"bodies": ["A7"]}, r"bodies\.0 = 'A7'.*'TCP'"),
    ({"configurations": [{"name": "X", "q_deg": [0, 40, 0, 0, 30, 0]}]},
     r"configurations\.0\.q_deg\.1 = 40 is outside joint 2's limits \[-155, 35\]"),
    ({"configurations": [{"name": "X", "q_deg": [0, -40, 0, 0, 30]}]}, r"configurations\.0\.q_deg"),
    ({"configurations": [CONFIGS[0], CONFIGS[0]]}, r"name = 'R1' is used twice"),
    ({"configurations": []}, r"no configurations"),
    ({"random_configurations": {"count": 2, "margin_deg": 200}}, r"margin_deg = 200 leaves no room"),
    ({"truth": "missing.yaml"}, r"truth = 'missing.yaml': model file .* not found"),
    ({"sed": 3}, r"sed is not a known key"),
])
def test_bad_campaign_files_name_file_key_and_value(tmp_path, change, message):
    path = write_campaign(tmp_path, name="bad.yaml", **change)
    with pytest.raises(ConfigError, match=message) as info:
        Campaign.from_yaml(path)
    assert "bad.yaml" in str(info.value)


def test_cli_reports_bad_campaign_with_exit_code_2(tmp_path, capsys):
    path = write_campaign(tmp_path, name="bad.yaml", loads={"max_N": 0})
    assert main(["simulate", str(path), "-o", str(tmp_path / "x.csv")]) == 2
    err = capsys.readouterr().err
    assert "bad.yaml" in err and "loads.max_N" in err and "Traceback" not in err
