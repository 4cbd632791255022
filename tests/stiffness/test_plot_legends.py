"""Every plot keeps its legend off the data: no legend's box overlaps any axes' box once drawn (the
diagnose plots, the compare bar plots and the HIL circle)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from matplotlib.figure import Figure

from stiffness.data.measurements import read_measurements
from stiffness.diagnose.discovery import diagnose
from stiffness.diagnose.plots import evidence, residual_vs_force, residual_vs_time
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.report.plots import rms_bars
from testlib.common import MODELS, ROOT


def legends_off_the_data(fig: Figure) -> int:
    """Draw ``fig``; assert no legend overlaps an axes; return the number of legends."""
    fig.draw_without_rendering()
    legends = list(fig.legends) + [ax.get_legend() for ax in fig.axes if ax.get_legend() is not None]
    for leg in legends:
        box = leg.get_window_extent()
        for ax in fig.axes:
            assert not box.overlaps(ax.get_window_extent()), (leg.get_texts()[0].get_text(), ax.get_title())
    return len(legends)


@pytest.fixture(scope="module")
def diagnosis():
    model = StiffnessModel.from_yaml(MODELS / "kr125_axial.yaml")
    data = read_measurements(ROOT / "examples" / "campaign_backlash.csv", model.robot)
    return diagnose(model, data.subset(np.isin(data.config, data.configs[:2])))


def test_diagnose_plots(diagnosis):
    d = diagnosis
    for fig in (evidence(d.candidates[0], d.ctx, d.fit.residual, d.fit.sigma), residual_vs_time(d.ctx, d.fit.residual),
                residual_vs_force(d.ctx, d.fit.residual)):
        assert legends_off_the_data(fig) == 1


def test_compare_bar_plots():
    tall = {b: {"rms_position_mm": 1.0, "rms_rotation_deg": 0.1} for b in ("A1", "A2", "TCP")}
    fig = rms_bars([("before", tall), ("after", tall)], "body", noise=(0.03, 0.002))
    assert legends_off_the_data(fig) == 1


def test_hil_circle_plot():
    from hil.report import circle_figure, evaluate_uncompensated
    from hil.robot_stub import RobotStub
    from hil.scenario import load_scenario
    from hil.testing import TRUTH
    from hil.world import World
    sc = load_scenario()
    truth = StiffnessModel.from_yaml(TRUTH)
    world = World(sc, truth.robot)
    ev = evaluate_uncompensated(world, RobotStub(truth, sc.robot), sc.plc.period_ms / 1e3)
    compensated = dataclasses.replace(ev, err_mm=ev.err_mm * 0.03)
    assert legends_off_the_data(circle_figure(world, {"uncompensated": ev, "compensated": compensated})) == 1
