"""The compare report's tables stay narrow: one row per group and model, one column per metric, so
neither a second model nor long model names widen them (issue 17: the by-body table ran past
1400 px with two models)."""

from __future__ import annotations

import re

import numpy as np
import yaml

from stiffness.compare.comparison import METRICS, compare, summary
from stiffness.compare.report import GROUPS, build_report, component_table, group_table
from stiffness.plan.simulate import Campaign
from testlib.common import ROOT

TRUTH = ROOT / "examples" / "truth_reference.yaml"
LONG = "kr125_6dof_with_backlash_fitted_on_the_campaign_of_the_second_shift"


def comparison(tmp_path, n_models: int):
    spec = {"truth": str(TRUTH), "seed": 3, "bodies": ["A3", "A6", "TCP"], "readings": {"repeats": 1},
            "configurations": [{"name": "R1", "q_deg": [10, -75, 90, 0, 75, 0]}]}
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(spec))
    c = Campaign.from_yaml(tmp_path / "c.yaml")
    models = []
    for k in range(n_models):
        m = c.truth.copy()
        m.theta = m.theta * (1 + 0.3 * k)
        m.name = f"{LONG}_{k}"
        models.append(m)
    return compare(models, c.run())


def test_group_and_component_tables_do_not_widen_with_models_or_names(tmp_path):
    one, two = comparison(tmp_path, 1), comparison(tmp_path, 2)
    for group, what in GROUPS:
        h1, rows1, _ = group_table(one, group, what)
        h2, rows2, _ = group_table(two, group, what)
        assert len(h2) == len(h1) + 1 == len(METRICS) + 3          # the group, the model, the rows, metrics
        assert max(len(h) for h in h2) <= len("load direction")      # no model name in a header
        assert len(rows2) == 2 * len(rows1)
        assert {r[1] for r in rows2} == {m.name for m in two.models}
    assert len(component_table(two)[0]) == len(component_table(one)[0]) + 1 == 6


def test_each_row_holds_its_models_metrics(tmp_path):
    comp = comparison(tmp_path, 2)
    header, rows, _ = group_table(comp, "by_body", "body")
    by_name = {m.name: m for m in comp.models}
    for row in rows:
        g = by_name[row[1]].metrics["by_body"][row[0]]
        assert row[2] == g["n_rows"]
        assert row[3:] == [g[m.key] for m in METRICS]
    assert header[3:] == [m.column for m in METRICS]


def test_the_summary_has_every_metric_in_order():
    y = np.arange(12.0).reshape(2, 6)
    assert list(summary(y, y * 0.9)) == [m.key for m in METRICS] + ["n_rows"]


def test_no_model_name_in_any_table_header(tmp_path):
    page = build_report(comparison(tmp_path, 2), plots=False).html()
    headers = re.findall(r"<tr>((?:<th>.*?</th>)+)</tr>", page)
    assert len(headers) == 1 + len(GROUPS) + 1
    assert all(LONG not in h for h in headers[1:])                 # the overall table names the models
