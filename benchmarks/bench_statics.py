"""The cost of tau_s for one configuration, as the 1 ms cycle would pay it when q changes (a script, not a test).

Side by side in one process, in alternating blocks (so the machine's drift falls on all alike):

* ``total_at``    `stiffness.kinematics.statics.Statics.total_at` with one q (arm + 80 kg payload + balancer),
                  the call the next step will make when the joints move;
* ``statics``     the batched `Statics.__call__` given one q (all parts, (1, 6) arrays each);
* ``pinocchio``   the two pinocchio calls inside it alone (generalized gravity, the payload centre's
                  Jacobian): what a leaner single-q path could reach;
* ``kinematics``  `service.compensation.FastPredictor.kinematics`, what the cycle already runs when q
                  changes, for scale.

The figure per item is the median over blocks of the mean time per call; the ratio is to kinematics.

    .venv/bin/python benchmarks/bench_statics.py [--blocks 20] [--calls 2000] [--json FILE]
"""

from __future__ import annotations

import argparse
import gc
import json
import sys
import time
from pathlib import Path

import numpy as np
import pinocchio as pin

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from service.compensation import FastPredictor
from stiffness.kinematics.statics import Statics
from stiffness.model.stiffness_model import StiffnessModel


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=20)
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--json")
    args = ap.parse_args()
    model = StiffnessModel.from_yaml(ROOT / "config" / "models" / "kr125_6dof.yaml")
    statics = Statics(model.robot, 80.0, (0.0, 0.0, 150.0))
    fp = FastPredictor(model)
    pm, pd, cog = statics.pm, statics.pd, statics.cog_id
    rng = np.random.default_rng(0)
    lo, hi = np.radians(model.robot.limits_deg).T
    qs = [np.ascontiguousarray(q) for q in rng.uniform(lo, hi, size=(256, 6)) * 0.7]

    def run_total_at(n):
        for k in range(n):
            statics.total_at(qs[k & 255])

    def run_statics(n):
        for k in range(n):
            statics(qs[k & 255])

    def run_pinocchio(n):
        for k in range(n):
            q = qs[k & 255]
            pin.computeGeneralizedGravity(pm, pd, q)
            pin.computeFrameJacobian(pm, pd, q, cog, pin.LOCAL_WORLD_ALIGNED)

    def run_kinematics(n):
        for k in range(n):
            fp.kinematics(qs[k & 255])

    items = {"total_at": run_total_at, "statics": run_statics, "pinocchio": run_pinocchio, "kinematics": run_kinematics}
    times: dict[str, list[float]] = {k: [] for k in items}
    for f in items.values():
        f(200)                                   # warm up
    gc.disable()
    for _ in range(args.blocks):
        for name, f in items.items():
            t0 = time.perf_counter()
            f(args.calls)
            times[name].append((time.perf_counter() - t0) / args.calls)
    gc.enable()
    med = {k: float(np.median(v)) for k, v in times.items()}
    result = {"blocks": args.blocks, "calls_per_block": args.calls,
              "median_us": {k: v * 1e6 for k, v in med.items()},
              "ratio_to_kinematics": {k: v / med["kinematics"] for k, v in med.items()}}
    print(f"{args.blocks} blocks x {args.calls} calls, one q per call; median of the block means:")
    for k in items:
        print(f"  {k:11s} {med[k] * 1e6:8.1f} us   {med[k] / med['kinematics']:5.2f} x kinematics")
    if args.json:
        Path(args.json).write_text(json.dumps(result, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
