"""The cycle's work with every effect of the library against the springs alone (a script, not a test).

One whole `service.pipeline.Cycle.step` per cycle, as the service runs it when a robot moves: a new
sensor sample and new joint positions every cycle (so `kinematics` runs every cycle too), the PLC
enabled. The models: config/models/kr125_6dof.yaml (springs only), the same with one effect added,
and the same with every effect of the library (backlash, hysteresis, nonlinear stiffness, link bending
of a link whose beam depends on q and of one whose beam does not, sensor misalignment, drift). The
models run in alternating blocks of cycles in one process, so the machine's drift falls on all alike;
the figure is the ratio of the medians of the per-block mean cycle times. "every effect, preloaded" is the
every-effect model on the KR 125 with its masses (config/robots/kr125_masses.yaml): the static torque is
formed at every kinematics and the axial effects act at the total torque. "every effect, preload
identified" is the every-effect model on the KR 125 without masses holding an identified static torque
at joints 2 and 3 (the model's ``preload``; one static regressor pass more at each kinematics).

    .venv/bin/python benchmarks/bench_effects.py [--blocks 30] [--cycles 1000] [--json FILE]
"""

from __future__ import annotations

import argparse
import gc
import json
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hil.testing import BEYOND_SPRINGS, model_with
from plc_interface.contract import Command
from service.ati import Reading
from service.config import load_config
from service.pipeline import Cycle
from stiffness.model import StiffnessModel
from stiffness.robot import load_robot


class Runner:
    """One model's cycle, driven like a moving robot under a milling load."""

    def __init__(self, m: StiffnessModel):
        cfg = load_config(ROOT / "config" / "default.yaml")
        self.cycle = Cycle.from_config(cfg, m)
        self.t = 0.0
        self.k = 0
        rng = np.random.default_rng(1)
        n = 4096
        phase = np.linspace(0, 8 * np.pi, n)
        self.w = [[300 * np.cos(p) + 5 * a, 300 * np.sin(p) + 5 * b, 150.0 + 5 * c, 20 * np.sin(p), 20 * np.cos(p), 1.0]
                  for p, a, b, c in zip(phase, *rng.standard_normal((3, n)))]
        self.q = [[10 + 2 * np.sin(p), -70 + np.cos(p), 95.0, 15.0, 40 + np.sin(p), -20.0] for p in phase]

    def run(self, cycles: int) -> float:
        """Mean seconds per cycle over ``cycles`` cycles."""
        step, enable = self.cycle.step, int(Command.ENABLE)
        t0 = time.perf_counter()
        for _ in range(cycles):
            self.t += 0.001
            self.k += 1
            i = self.k & 4095
            step(self.t, Reading(self.w[i], 0, self.k, False), [], enable, self.k, self.q[i])
        return (time.perf_counter() - t0) / cycles


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=30)
    ap.add_argument("--cycles", type=int, default=1000)
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    models = {"springs only": model_with(base="kr125_6dof")}
    for e in BEYOND_SPRINGS:
        m = model_with(e, base="kr125_6dof")
        models[f"+ {m.effects[-1].label}"] = m
    models["every effect"] = every = model_with(*BEYOND_SPRINGS, base="kr125_6dof")
    # the same on the KR 125 with its masses: the axial effects at tau_s(q) + tau_ext, tau_s formed at
    # each kinematics (the arm's weight, its balancer, the gravity section's payload)
    models["every effect, preloaded"] = StiffnessModel.from_dict(
        every.to_dict(), "every effect, preloaded", robot=load_robot(ROOT / "config" / "robots" / "kr125_masses.yaml"))
    # the same on the KR 125 without masses, its static torque identified at joints 2 and 3 (`preload`)
    identified = every.to_dict()
    identified["preload"] = [{"joint": 2, "my2_kgm": -40.0, "m3_kg": 30.0}, {"joint": 3, "mx3_kgm": 12.0}]
    models["every effect, preload identified"] = StiffnessModel.from_dict(
        identified, "every effect, preload identified", robot=every.robot)
    runners = {k: Runner(m) for k, m in models.items()}
    for r in runners.values():
        r.run(200)                                            # warm up
    times: dict[str, list[float]] = {k: [] for k in runners}
    gc.disable()
    try:
        for _ in range(args.blocks):
            for k, r in runners.items():
                times[k].append(r.run(args.cycles))
    finally:
        gc.enable()
    base = float(np.median(times["springs only"]))
    out = {k: {"median_us": float(np.median(v)) * 1e6, "ratio": float(np.median(v)) / base} for k, v in times.items()}
    w = max(len(k) for k in out)
    print(f"{'model':<{w}}  cycle work (median of {args.blocks} blocks of {args.cycles})  ratio to springs only")
    for k, v in out.items():
        print(f"{k:<{w}}  {v['median_us']:8.1f} µs {'':30} {v['ratio']:.3f}")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
