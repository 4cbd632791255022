"""How long `stiffcomp plan` takes, and what robust identification buys on gross errors.

Run: .venv/bin/python benchmarks/bench_plan.py [--repeat 3]

* plan: wall time of `stiffness.plan.design.plan` for kr125_6dof with a 6-D optical device, N = 4 and
  N = 8 (median of --repeat runs), with the plan's criterion against the median of random sets;
* robust vs plain: a simulated campaign (5 random configurations, 2 readings per load state) with
  1 % of rows off by 0.4 mm; the worst axial stiffness error of each fit, the residual RMS over the
  noise, and the outliers' precision and recall. Ratios, not absolute times, are what carry over
  from a shared machine.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests")]

from discovery.campaigns import campaign, start_model, with_gross_errors

from hil.testing import truth_with
from stiffness.fit.identify import fit
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.plan.design import Device, plan


def bench_plan(repeat: int) -> None:
    model = StiffnessModel.from_yaml(ROOT / "config/models/kr125_6dof.yaml")
    device = Device.named("optical6d", model)
    for n in (4, 8):
        times, p = [], None
        for _ in range(repeat):
            t = time.perf_counter()
            p = plan(model, device, n)
            times.append(time.perf_counter() - t)
        print(f"plan N={n}: {statistics.median(times):.2f} s (median of {repeat}); worst relative std error "
              f"{p.criterion:.4f} vs random median {p.random_median:.4f} (ratio {p.criterion / p.random_median:.2f})")


def bench_robust(seeds=(41, 42, 44)) -> None:
    truth = truth_with([])
    want = {e.joint: e.theta[5] for e in truth.effects}
    for seed in seeds:
        data, bad = with_gross_errors(campaign(truth, seed), seed=seed)
        line = [f"seed {seed}: {len(bad)} bad rows of {len(data)}"]
        for robust in (True, False):
            t = time.perf_counter()
            r = fit(start_model(), data, robust=robust)
            dt = time.perf_counter() - t
            got = {e.joint: e.theta[5] for e in r.model.effects}
            err = max(abs(got[j] / want[j] - 1) for j in want)
            flagged = np.nonzero(r.outlier)[0]
            hit = np.isin(bad, flagged).sum()
            prec = hit / len(flagged) if len(flagged) else float("nan")
            line.append(f"{'robust' if robust else 'plain '}: worst axial error {100 * err:.2f} %, "
                        f"RMS {r.rms_position_mm / 0.03:.2f}x noise, precision {prec:.2f}, "
                        f"recall {hit / len(bad):.2f}, {dt:.2f} s")
        print("\n  ".join(line))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=3)
    args = ap.parse_args()
    bench_plan(args.repeat)
    bench_robust()


if __name__ == "__main__":
    main()
