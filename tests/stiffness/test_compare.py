"""Model against measurement: exact on its own noise-free data, hand-computed metrics, two-model order,
the JSON structure and the HTML report."""

import json

import numpy as np
import pytest
import yaml

from stiffness.compare.comparison import by_component, compare, load_direction, r2, summary
from stiffness.data.measurements import Dataset
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.plan.simulate import Campaign
from testlib.common import ROOT
from tools.cli import main

TRUTH = ROOT / "examples" / "truth_reference.yaml"
ROBOT = ROOT / "config" / "robots" / "kr125.yaml"


def campaign(tmp_path, bodies=("A1", "A2", "A3", "A4", "A5", "A6", "TCP"), seed=1):
    spec = {"truth": str(TRUTH), "seed": seed, "bodies": list(bodies), "readings": {"repeats": 1},
            "configurations": [{"name": "R1", "q_deg": [10, -75, 90, 0, 75, 0]},
                               {"name": "R3", "q_deg": [40, -85, 115, -60, 55, 45]}]}
    path = tmp_path / "campaign.yaml"
    path.write_text(yaml.safe_dump(spec))
    return Campaign.from_yaml(path)


def softer(model: StiffnessModel, factor: float, name: str) -> StiffnessModel:
    m = model.copy()
    m.theta = m.theta * factor
    m.name = name
    return m


def save(model: StiffnessModel, path) -> str:
    model.to_yaml(path)
    return str(path)


def test_model_on_its_own_noise_free_data_has_no_error(tmp_path):
    c = campaign(tmp_path)
    data = c.run(noise=False)
    m = compare([c.truth], data).models[0].metrics
    assert m["rms_position_mm"] == 0.0 and m["rms_rotation_deg"] == 0.0
    assert m["max_position_mm"] == 0.0 and m["max_rotation_deg"] == 0.0
    assert m["r2_position"] == 1.0 and m["r2_rotation"] == 1.0
    for group in ("by_body", "by_config", "by_load_direction"):
        for g in m[group].values():
            assert g["rms_position_mm"] == 0.0 and g["r2_position"] == 1.0 and g["r2_rotation"] == 1.0
    assert set(m["by_body"]) == {"A1", "A2", "A3", "A4", "A5", "A6", "TCP"}
    assert list(m["by_config"]) == ["R1", "R3"]
    assert list(m["by_load_direction"]) == ["+x", "-x", "+y", "-y", "+z", "-z", "none"]
    assert all(g["r2"] == 1.0 for g in m["by_component"].values())


def test_metrics_by_hand():
    y = np.array([[1, 2, 0, 0.1, 0, 0], [3, 2, 4, 0.3, 0, 0]], dtype=float)
    yhat = np.array([[1, 1, 0, 0.0, 0, 0], [2, 2, 4, 0.3, 0, 0]], dtype=float)
    s = summary(y, yhat)
    assert s["rms_position_mm"] == pytest.approx(np.sqrt(2 / 6))
    assert s["max_position_mm"] == pytest.approx(1.0)
    assert s["r2_position"] == pytest.approx(1 - 2 / 10)     # SS_tot: (1-2)^2 + (3-2)^2 + (0-2)^2 + (4-2)^2
    assert s["rms_rotation_deg"] == pytest.approx(np.sqrt(0.01 / 6))
    assert s["max_rotation_deg"] == pytest.approx(0.1)
    assert s["r2_rotation"] == pytest.approx(1 - 0.01 / 0.02)
    assert s["n_rows"] == 2
    comp = by_component(y, yhat)
    assert comp["dx"]["rms"] == pytest.approx(np.sqrt(0.5)) and comp["dx"]["r2"] == pytest.approx(0.5)
    assert np.isnan(comp["dy"]["r2"])                        # no spread but an error: undefined
    assert comp["dz"]["r2"] == 1.0 and comp["rx"]["unit"] == "deg"
    assert r2(np.zeros((3, 2)), np.zeros((3, 2))) == 1.0


def test_load_direction_by_hand():
    F = np.array([[100, 0, 0], [0, -50, 10], [0, 0, 3], [0, 0, -5.1], [-2, 1, 0]], dtype=float)
    data = Dataset(np.arange(5.0), ["C"] * 5, np.zeros((5, 6)), np.hstack([F, np.zeros((5, 3))]),
                   [6] * 5, np.zeros((5, 6)))
    labels, threshold = load_direction(data)
    assert threshold == pytest.approx(5.0)
    assert labels.tolist() == ["+x", "-y", "none", "-z", "none"]


def test_end_to_end_against_hand_values():
    """A model that predicts nothing: the error is the measurement itself, grouped by hand."""
    model = StiffnessModel.from_dict({"robot": str(ROBOT), "effects": [
        {"effect": "joint_spring", "joint": 1, "rz_rad_per_Nm": 0.0}]})
    F = np.array([[100.0, 0, 0], [1.0, 0, 0], [0, 0, -80.0]])
    defl = np.array([[0.3, 0, 0.4, 0, 0, 0.01], [0.1, 0, 0, 0, 0, 0], [0, -0.2, 0, 0.02, 0, 0]])
    data = Dataset(np.arange(3.0), ["A", "A", "B"], np.tile([0, -60, 60, 0, 60, 0], (3, 1)),
                   np.hstack([F, np.zeros((3, 3))]), [6, 6, 6], defl)
    m = compare([model], data).models[0].metrics
    assert m["rms_position_mm"] == pytest.approx(np.sqrt((0.09 + 0.16 + 0.01 + 0.04) / 9))
    assert m["max_position_mm"] == pytest.approx(0.4)
    assert m["by_config"]["B"]["rms_rotation_deg"] == pytest.approx(np.sqrt(0.02 ** 2 / 3))
    assert m["by_load_direction"]["none"]["rms_position_mm"] == pytest.approx(np.sqrt(0.01 / 3))
    assert set(m["by_load_direction"]) == {"+x", "-z", "none"}
    assert m["by_component"]["dz"]["rms"] == pytest.approx(np.sqrt(0.16 / 3))


def test_two_models_in_the_right_order(tmp_path):
    c = campaign(tmp_path)
    data = c.run()
    worse = softer(c.truth, 1.4, "too_soft")
    falls = compare([worse, c.truth], data)
    assert falls.better() == c.truth.name
    ch = falls.change()
    assert ch["rms_position_mm"]["relative"] < -0.3 and ch["rms_rotation_deg"]["relative"] < -0.3
    assert ch["r2_position"]["change"] > 0
    text, kind = falls.verdict()
    assert kind == "good" and "falls" in text
    rises = compare([c.truth, worse], data)
    assert rises.better() == c.truth.name and rises.verdict()[1] == "bad"
    assert rises.change()["rms_position_mm"]["relative"] > 0.3
    # the truth model sits at the noise level of the campaign
    truth = falls.models[1].metrics
    assert truth["rms_position_mm"] == pytest.approx(0.03, rel=0.1)
    assert truth["rms_rotation_deg"] == pytest.approx(0.002, rel=0.1)


def test_cli_json_has_the_documented_keys(tmp_path, capsys):
    c = campaign(tmp_path, bodies=("A3", "TCP"))
    data_path = tmp_path / "data.csv"
    c.run().to_csv(data_path)
    a = save(softer(c.truth, 0.7, "stiff"), tmp_path / "stiff.yaml")
    b = save(c.truth.copy(), tmp_path / "truth.yaml")
    assert main(["compare", a, b, str(data_path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("data", "rows", "configurations", "load_threshold_N", "models", "change", "better",
                "verdict", "verdict_kind"):
        assert key in out
    assert [m["name"] for m in out["models"]] == ["stiff", "truth_reference"]
    for m in out["models"]:
        for key in ("rms_position_mm", "rms_rotation_deg", "max_position_mm", "max_rotation_deg",
                    "r2_position", "r2_rotation", "by_body", "by_component", "by_config", "by_load_direction"):
            assert key in m
        assert set(m["by_body"]) == {"A3", "TCP"}
        assert set(m["by_component"]) == {"dx", "dy", "dz", "rx", "ry", "rz"}
        assert set(m["by_body"]["TCP"]) >= {"rms_position_mm", "r2_rotation", "n_rows"}
    assert out["change"]["rms_position_mm"]["to"] < out["change"]["rms_position_mm"]["from"]
    assert out["better"] == "truth_reference" and out["verdict_kind"] == "good"


def test_cli_report_writes_index_and_pngs(tmp_path, capsys):
    c = campaign(tmp_path, bodies=("A2", "TCP"))
    data_path = tmp_path / "data.csv"
    c.run().to_csv(data_path)
    a = save(softer(c.truth, 1.5, "soft"), tmp_path / "soft.yaml")
    report = tmp_path / "report"
    assert main(["compare", a, str(data_path), "--report", str(report)]) == 0
    assert "report:" in capsys.readouterr().out
    page = (report / "index.html").read_text()
    pngs = sorted(p.name for p in report.glob("*.png"))
    assert {f"load_{c}.png" for c in ("dx", "dy", "dz", "rx", "ry", "rz")} <= set(pngs)
    assert "rms_by_body.png" in pngs
    for name in pngs:
        assert f'src="{name}"' in page
        assert (report / name).read_bytes()[:4] == b"\x89PNG"
    assert page.index('class="verdict') < page.index("<table>")
    assert "soft" in page and "R²" in page


def test_cli_needs_one_or_two_models_and_data(tmp_path, capsys):
    assert main(["compare", str(TRUTH)]) == 2
    assert "MODEL [MODEL2] DATA" in capsys.readouterr().err
