"""diagnose's views: "Where the model fails" is in units of the noise of repeated readings, as its label
says, and the long commands show their progress on stderr."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest

from stiffness.data.measurements import COMPONENTS, read_measurements
from stiffness.diagnose.discovery import diagnose
from stiffness.diagnose.report import build_report
from stiffness.fit.result import rms
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import MODELS, ROOT

pytestmark = pytest.mark.slow

WALK = ROOT / "examples" / "campaign_backlash.csv"


@pytest.fixture(scope="module")
def diagnosis():
    model = StiffnessModel.from_yaml(MODELS / "kr125_axial.yaml")
    data = read_measurements(WALK, model.robot)
    return diagnose(model, data.subset(np.isin(data.config, data.configs[:3])))


def test_where_the_model_fails_divides_by_the_noise_of_repeated_readings(diagnosis):
    d = diagnosis
    assert d.noise is not None and d.lack_of_fit["reference"] == "repeated readings"
    resid = d.fit.residual[d.fit.inlier]
    for k, c in enumerate(COMPONENTS):
        noise = d.noise["position_mm"] if k < 3 else d.noise["rotation_deg"]
        assert d.worst["scores"]["component"][c] == pytest.approx(rms(resid[:, k]) / noise, rel=1e-9)
    # the model lacks the backlash: its residual is well above the noise, so the table shows > 1
    assert max(d.worst["scores"]["component"].values()) > 1.5
    assert "RMS in units of the noise of repeated readings" in build_report(d, "m.yaml", "d.csv", plots=False).html()


def test_diagnose_and_fit_show_progress_on_stderr(tmp_path):
    r = subprocess.run([sys.executable, "-m", "tools.cli", "diagnose", MODELS / "kr125_axial.yaml", WALK, "--json"],
                       cwd=ROOT, capture_output=True, check=False, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    lines = r.stderr.splitlines()
    assert lines[0].startswith("diagnose: fitting the model (") and any(
        x.startswith("diagnose: done in ") for x in lines)
    assert r.stdout.lstrip().startswith("{")                  # stdout stays the result
    f = subprocess.run([sys.executable, "-m", "tools.cli", "fit", MODELS / "kr125_axial.yaml", WALK, "--json"],
                       cwd=ROOT, capture_output=True, check=False, text=True, timeout=300)
    assert f.stderr.startswith("fit: fitting 6 parameters to ") and "fit: done in " in f.stderr
