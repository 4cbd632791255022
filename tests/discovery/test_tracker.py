"""Laser-tracker campaigns (issue 12): the TCP position only, no rotation, no joint frames.

The axial model fitted to a tracker campaign made from a known axial truth recovers the axial
stiffness of joints 1-5 within 5 %; joint 6's axial compliance moves nothing the tracker sees (the
TCP lies on joint 6's axis) and is named, and kept at its starting value.
"""

import json

import numpy as np
import pytest

from discovery.campaigns import campaign, start_model, tracker
from hil.testing import truth_with
from stiffness.compare.comparison import compare
from stiffness.data.measurements import read_measurements
from stiffness.diagnose.discovery import diagnose
from stiffness.fit.identify import fit
from testlib.common import MODELS
from tools.cli import main

J6_AXIAL = "joint_spring@joint6.rz_rad_per_Nm"


@pytest.fixture(scope="module")
def axial_truth():
    return truth_with([], axial_except=0)       # every joint an axial spring only


@pytest.fixture(scope="module")
def tracker_csv(tmp_path_factory, axial_truth):
    path = tmp_path_factory.mktemp("tracker") / "tracker.csv"
    tracker(campaign(axial_truth, 50, configs=5, repeats=2)).to_csv(path)
    return path


def test_tracker_file_round_trips_with_position_columns_only(tracker_csv):
    header = tracker_csv.read_text().splitlines()[0].split(",")
    assert header[-4:] == ["body", "dx_mm", "dy_mm", "dz_mm"]
    data = read_measurements(tracker_csv)
    assert data.measured[:, :3].all() and not data.measured[:, 3:].any()


def test_identifiable_axial_stiffness_is_recovered_and_the_rest_named(tracker_csv, axial_truth):
    start = start_model("kr125_axial")
    result = fit(start, read_measurements(tracker_csv))
    assert result.unidentifiable == [J6_AXIAL]
    assert np.isinf(result.std_error[-1])
    truth = {e.joint: e.theta[0] for e in axial_truth.effects}
    for e in result.model.effects[:5]:
        assert e.theta[0] == pytest.approx(truth[e.joint], rel=0.05), f"joint {e.joint}"
    assert result.model.effects[5].theta[0] == start.effects[5].theta[0]     # kept at the start
    assert np.isnan(result.rms_rotation_deg) and result.rms_position_mm == pytest.approx(0.03, rel=0.1)


def test_36_parameter_model_names_what_positions_cannot_separate(tracker_csv):
    result = fit(start_model("kr125_6dof"), read_measurements(tracker_csv))
    assert J6_AXIAL in result.unidentifiable
    assert all(lab in result.undetermined for lab in result.unidentifiable)
    # what is not named is determined: it has a finite standard error
    named = np.isin(start_model("kr125_6dof").param_labels(), result.unidentifiable)
    assert np.isfinite(result.std_error[~named]).all()


def test_compare_and_diagnose_use_the_measured_components_only(tracker_csv, axial_truth):
    data = read_measurements(tracker_csv)
    comp = compare([axial_truth], data).models[0].metrics
    assert comp["rms_position_mm"] == pytest.approx(0.03, rel=0.1)
    assert np.isnan(comp["rms_rotation_deg"]) and np.isnan(comp["by_component"]["rx"]["rms"])
    d = diagnose(start_model("kr125_axial"), data)
    assert d.verdict == "no_missing_effect", d.message
    assert d.fit.unidentifiable == [J6_AXIAL]
    assert d.noise["position_mm"] == pytest.approx(0.03, rel=0.1) and np.isnan(d.noise["rotation_deg"])


def test_cli_fit_names_unidentifiable_and_outliers(tracker_csv, capsys):
    assert main(["fit", str(MODELS / "kr125_axial.yaml"), str(tracker_csv), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["unidentifiable"] == [J6_AXIAL]
    assert out["outliers"]["count"] == len(out["outliers"]["lines"])
    assert out["noise_estimate"]["rotation_deg"] is None
