"""Physics refused where it is impossible: a negative compliance is shown (not hidden as "not in the
model"), can be bounded by the fit, is warned about by compare and refused by the service at start-up."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from hil.testing import write_config
from stiffness.errors import ConfigError
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import DATA, MODELS
from testlib.common import run_cli as stiffcomp

pytestmark = pytest.mark.slow

CAMPAIGN = DATA / "reference_campaign.csv"




def negative_model(tmp_path, entry: dict | None = None):
    """kr125_axial with joint 3's axial compliance negative (or ``entry`` added)."""
    m = StiffnessModel.from_yaml(MODELS / "kr125_axial.yaml")
    d = m.to_dict()
    if entry is None:
        d["effects"][2]["rz_rad_per_Nm"] = -2.0e-7
    else:
        d["effects"].append(entry)
    path = tmp_path / "negative.yaml"
    StiffnessModel.from_dict(d, str(path), robot=m.robot).to_yaml(path)
    return path


def test_the_service_refuses_a_negative_compliance_at_start_up_with_exit_2(tmp_path):
    model = negative_model(tmp_path)
    cfg = write_config(tmp_path, {"model": {"file": str(model)}})
    r = stiffcomp("run", "--config", cfg, "--duration", "30")
    assert r.returncode == 2, r.stderr[-3000:]
    assert "joint_spring@joint3.rz_rad_per_Nm = -2e-07 rad/Nm" in r.stderr
    assert "negative compliance" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("entry, key", [
    ({"effect": "link_bending", "link": 2, "compliance_per_Nm2": -1e-10}, "link_bending@link2.compliance_per_Nm2"),
    ({"effect": "joint_6dof", "joint": 4, "x_m_per_N": -1e-9}, "joint_6dof@joint4.x_m_per_N"),
])
def test_every_compliance_is_checked_by_the_model(tmp_path, entry, key):
    m = StiffnessModel.from_yaml(negative_model(tmp_path, entry))
    with pytest.raises(ConfigError, match=key.replace(".", r"\.")):
        m.require_physical()
    StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml").require_physical()     # the shipped ones pass


def test_fit_shows_a_negative_compliance_as_a_number_and_bounds_it_when_asked(tmp_path):
    free = stiffcomp("fit", MODELS / "kr125_6dof.yaml", CAMPAIGN, "--json")
    assert free.returncode == 0, free.stderr
    res = json.loads(free.stdout)
    springs = [p for p in res["parameters"] if p["effect"] == "joint_spring"]
    negative = [p for p in springs if p["value"] < 0]
    assert negative, "this campaign leaves some off-axis compliances below zero"
    for p in springs:
        c = p["key"].split("_")[0]                  # x_m_per_N .. rz_rad_per_Nm: the component comes first
        stiffness = res["joint_stiffness"][p["location"] - 1][c]
        assert stiffness == pytest.approx(1.0 / p["value"], rel=1e-3), (p, stiffness)   # negative shown too
    warning = [w for w in res["warnings"] if "negative compliance" in w]
    assert len(warning) == 1 and all(f"joint{p['location']}.{p['key']}" in warning[0] for p in negative)

    text = stiffcomp("fit", MODELS / "kr125_6dof.yaml", CAMPAIGN)
    assert "not in the model; < 0 a negative compliance" in text.stdout
    assert "negative compliance" in text.stderr

    out = tmp_path / "bounded.yaml"
    bounded = stiffcomp("fit", MODELS / "kr125_6dof.yaml", CAMPAIGN, "--json", "--nonnegative", "-o", out)
    assert bounded.returncode == 0, bounded.stderr
    b = json.loads(bounded.stdout)
    values = {(p["location"], p["key"]): p["value"] for p in b["parameters"] if p["effect"] == "joint_spring"}
    assert min(values.values()) >= 0.0
    active = [w for w in b["warnings"] if "non-negative bound is active" in w]
    assert len(active) == 1 and not any("negative compliance(s)" in w for w in b["warnings"])
    held = [k for k, v in values.items() if v == 0.0]
    assert held and all(f"joint{j}.{k}" in active[0] for j, k in held)
    # the bound costs little fit where the data could not tell those compliances from zero
    assert b["rms_position_mm"] <= 1.02 * res["rms_position_mm"]
    StiffnessModel.from_yaml(out).require_physical()            # a model the service accepts
    assert np.isfinite([v for v in values.values()]).all()


def test_compare_warns_on_a_negative_compliance(tmp_path):
    model = negative_model(tmp_path)
    r = stiffcomp("compare", MODELS / "kr125_axial.yaml", model, CAMPAIGN, "--json")
    assert r.returncode == 0, r.stderr
    assert "joint_spring@joint3.rz_rad_per_Nm = -2e-07 rad/Nm" in r.stderr and "stiffcomp run` refuses" in r.stderr
    assert yaml.safe_load(r.stdout)["models"]
