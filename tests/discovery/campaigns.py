"""Synthetic campaigns with hidden effects for the discovery tests (made by stiffness.plan.simulate)."""

from __future__ import annotations

import numpy as np

from stiffness.model.stiffness_model import StiffnessModel
from stiffness.plan.simulate import Campaign, CampaignSpec
from testlib.common import MODELS


def campaign(truth: StiffnessModel, seed: int, configs: int = 5, repeats: int = 2, step_N: float = 300,
             noise: bool = True):
    spec = CampaignSpec.model_validate({
        "name": f"hidden_{seed}", "truth": "-", "seed": seed,
        "configurations": [],
        "random_configurations": {"count": configs, "margin_deg": 25.0},
        "loads": {"axes": ["x", "y", "z"], "max_N": 1200, "step_N": step_N, "point_mm": [100, 0, 250]},
        "readings": {"repeats": repeats, "interval_s": 4, "settle_s": 8, "move_s": 30},
    })
    return Campaign(spec, truth, f"<hidden effect campaign seed {seed}>").run(noise)


def start_model(name: str = "kr125_6dof") -> StiffnessModel:
    return StiffnessModel.from_yaml(MODELS / f"{name}.yaml")


def with_gross_errors(data, fraction: float = 0.01, size_mm: float = 0.4, seed: int = 0):
    """A copy of ``data`` with ``fraction`` of its rows off by ``size_mm`` (position, a random
    direction), as an occluded LED gives; returns the copy and the (sorted) rows made bad."""
    rng = np.random.default_rng([seed, 99])
    bad = np.sort(rng.choice(len(data), size=max(1, round(fraction * len(data))), replace=False))
    out = data.subset(np.arange(len(data)))
    d = rng.standard_normal((len(bad), 3))
    out.deflection = out.deflection.copy()
    out.deflection[bad, :3] += size_mm * d / np.linalg.norm(d, axis=1, keepdims=True)
    return out, bad


def tracker(data):
    """What a laser tracker sees of ``data``: the TCP rows, position only (rotations not measured)."""
    out = data.subset(data.body == 6)
    out.deflection = out.deflection.copy()
    out.deflection[:, 3:] = np.nan
    return out
