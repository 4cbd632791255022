"""Benchmarks of the model core (issue 2, item 8). Run: .venv/bin/python benchmarks/bench_model.py

* batch prediction: body predictions per second over a whole campaign, on one core;
* identification: a fit of the 36-parameter model to the reference campaign, and to a 6,426-row
  campaign (the size the issue names).

Each figure is the median of several repetitions, timed with time.perf_counter in this process.
"""

from __future__ import annotations

import json
import os
import statistics
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")       # one core
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from stiffness.data.measurements import Dataset, read_measurements
from stiffness.fit.identify import fit
from stiffness.model.stiffness_model import StiffnessModel


def median_time(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def tiled(data: Dataset, rows: int) -> Dataset:
    """A campaign of ``rows`` rows made by repeating the reference with new times and configs."""
    reps = -(-rows // len(data))
    idx = np.tile(np.arange(len(data)), reps)[:rows]
    out = data.subset(idx)
    k = np.repeat(np.arange(reps), len(data))[:rows]
    out.time_s = out.time_s + k * (data.time_s.max() + 10)
    out.config = np.char.add(out.config, np.char.mod("_%d", k))
    return out


def main() -> dict:
    model = StiffnessModel.from_yaml(ROOT / "config/models/kr125_6dof.yaml")
    ref = read_measurements(ROOT / "tests/data/reference_campaign.csv", model.robot)
    big = tiled(ref, 64_260)
    ctx = model.context(big)
    t_pred = median_time(lambda: model.predict(ctx), 7)
    t_pred_cold = median_time(lambda: model.predict(big), 3)
    t_fit = median_time(lambda: fit(model, ref), 5)
    campaign_6426 = tiled(ref, 6426)
    t_fit_6426 = median_time(lambda: fit(model, campaign_6426), 5)
    out = {
        "batch_prediction_rows": len(big),
        "body_predictions_per_s": len(big) / t_pred,
        "body_predictions_per_s_including_kinematics": len(big) / t_pred_cold,
        "fit_reference_5355_rows_s": t_fit,
        "fit_6426_rows_s": t_fit_6426,
    }
    return out


if __name__ == "__main__":
    print(json.dumps(main(), indent=2))
