"""Data sanity in words: duplicate rows and a body measured twice in a reading are named and left out
(or kept when asked); a noise far from the model's names the likely unit slip."""

from __future__ import annotations

import json

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from stiffness.data.measurements import read_measurements
from stiffness.fit.identify import fit
from stiffness.fit.sanity import duplicate_rows, noise_warning, resolve_duplicates
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import DATA, MODELS
from testlib.common import run_cli as stiffcomp

pytestmark = pytest.mark.slow

CAMPAIGN = DATA / "reference_campaign.csv"


@pytest.fixture(scope="module")
def axial():
    return StiffnessModel.from_yaml(MODELS / "kr125_axial.yaml")


@pytest.fixture(scope="module")
def campaign(axial):
    return read_measurements(CAMPAIGN, axial.robot)


@settings(max_examples=30, deadline=None)
@given(st.data())
def test_exact_copies_and_second_measurements_are_found_and_left_out(campaign, data):
    base = campaign.subset(np.arange(140))                       # 20 readings of 7 bodies
    copies = data.draw(st.lists(st.integers(0, 139), min_size=1, max_size=30))
    changed = data.draw(st.lists(st.integers(0, 139), max_size=10, unique=True))
    changed = [r for r in changed if r not in copies]
    rows = np.r_[np.arange(140), copies, changed].astype(int)
    order = np.r_[np.arange(140), 140 + np.array(data.draw(st.permutations(range(len(rows) - 140))), dtype=int)]
    d = base.subset(rows[order])
    d.deflection[140:] += np.where(np.isin(rows[order][140:], changed), 1e-3, 0.0)[:, None]
    exact, same_body = duplicate_rows(d)
    assert exact.sum() == len(copies) and same_body.sum() == len(changed)
    assert not (exact[:140] | same_body[:140]).any()             # the first copy is never flagged
    kept, warnings = resolve_duplicates(d)
    assert len(kept) == 140 and np.array_equal(kept.line, base.line)
    assert len(warnings) == 1 + bool(changed) and "left out" in warnings[0]
    same, kept_warnings = resolve_duplicates(d, keep=True)
    assert same is d and all("kept" in w for w in kept_warnings)


def test_a_clean_campaign_has_no_duplicates(campaign):
    assert not any(m.any() for m in duplicate_rows(campaign))
    assert resolve_duplicates(campaign) == (campaign, [])


def test_millimetres_given_as_metres_are_named(axial, campaign):
    ctx = axial.context(campaign)
    assert noise_warning(axial, ctx, campaign.deflection) is None
    in_m = campaign.subset(np.arange(len(campaign)))
    in_m.deflection = campaign.deflection * 1e-3
    w = noise_warning(axial, axial.context(in_m), in_m.deflection)
    assert w is not None and "millimetres given as metres" in w and "position" in w
    assert any("millimetres given as metres" in x for x in fit(axial, in_m).warnings)




def test_fit_on_every_row_twice_warns_and_leaves_the_copies_out(tmp_path, campaign):
    doubled = tmp_path / "doubled.csv"
    campaign.subset(np.repeat(np.arange(len(campaign)), 2)).to_csv(doubled)
    once = json.loads(stiffcomp("fit", MODELS / "kr125_axial.yaml", CAMPAIGN, "--json").stdout)
    r = stiffcomp("fit", MODELS / "kr125_axial.yaml", doubled, "--json")
    assert r.returncode == 0, r.stderr
    assert f"{len(campaign)} row(s) repeat an earlier row exactly" in r.stderr and "left out" in r.stderr
    dropped = json.loads(r.stdout)
    assert dropped["rms_position_mm"] == pytest.approx(once["rms_position_mm"], rel=1e-9)
    k = stiffcomp("fit", MODELS / "kr125_axial.yaml", doubled, "--json", "--keep-duplicates")
    assert k.returncode == 0 and "kept (as asked)" in k.stderr
    assert json.loads(k.stdout)["parameters"][0]["value"] == pytest.approx(once["parameters"][0]["value"], rel=1e-6)
