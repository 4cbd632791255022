"""The per-cycle cost of a payload switch (a script, not a test).

Side by side in one process, in alternating blocks (so the machine's drift falls on all alike), on the
KR 125 with link masses and a backlash at joint 2 (so tau_s and the effects at the total torque count):

* ``carry``          `FastPredictor.carry` + `kinematics`: a new Statics (a copy of the pinocchio model)
                     per call, what blending tau_s would cost by rebuilding it;
* ``carry_payload``  `FastPredictor.carry_payload`: `Statics.carry` moves the payload in place, tau_s
                     at the last joints and the axial f(tau_s);
* ``kinematics``     `FastPredictor.kinematics`, what a cycle pays when the joints move, for scale;
* ``ramp``           `PayloadSelector.update` in a ramp: the blend into the gravity compensation and
                     tau_s, what a cycle pays during a switch;
* ``idle``           `PayloadSelector.update` with no switch, what every other cycle pays;
* ``cycle``          `Compensator.cycle` with a sample, for scale.

The figure per item is the median over blocks of the mean time per call, in us.

    .venv/bin/python benchmarks/bench_payload_switch.py [--blocks 15] [--calls 2000] [--json FILE]
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

from service.ati import Reading
from service.compensation import FastPredictor
from service.faults import FaultMonitor
from service.filters import FilterConfig, SosLowPass, SpikeRejector
from service.gravity import GravityCompensator, GravityConfig
from service.limits import CorrectionLimiter
from service.payloads import PayloadSelector
from service.pipeline import Compensator
from stiffness.effects.backlash import Backlash
from stiffness.model.stiffness_model import StiffnessModel

G = [0.0, 0.0, -9.81]


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=15)
    ap.add_argument("--calls", type=int, default=2000)
    ap.add_argument("--json")
    args = ap.parse_args()
    d = StiffnessModel.from_yaml(ROOT / "config" / "models" / "kr125_6dof.yaml").to_dict()
    d["robot"] = str(ROOT / "config" / "robots" / "kr125_masses.yaml")
    d["effects"] += [{"effect": Backlash.name, "joint": 2, "lost_motion_deg": 0.02, "width_Nm": 40.0}]
    model = StiffnessModel.from_dict(d, "kr125_6dof on kr125_masses")
    q = np.radians([10.0, -80.0, 100.0, 20.0, 40.0, 30.0])
    section = GravityConfig(payloads=[{"index": 1, "name": "a", "mass_kg": 14.0, "cog_mm": [0, 0, 130]},
                                      {"index": 2, "name": "b", "mass_kg": 6.0, "cog_mm": [0, 20, 80]}],
                            switch_ramp_s=60.0)          # longer than a block: every call blends
    fp = FastPredictor(model)
    gravity = GravityCompensator.from_config(section)
    comp = Compensator(fp, SosLowPass.from_config(FilterConfig(), 1e-3),
                       SpikeRejector([300.0] * 3 + [30.0] * 3), gravity, CorrectionLimiter([0.5] * 6, [5.0] * 6, 0.2), FaultMonitor())
    ramping = PayloadSelector.from_config(section, gravity, fp, comp.faults)
    idle = PayloadSelector.from_config(section, GravityCompensator.from_config(section), FastPredictor(model),
                                       FaultMonitor())
    fp.kinematics(q)
    reading = Reading([10.0, -20.0, 130.0, 1.0, 2.0, 0.5], 0, 0, False)

    def run_carry(n):
        for k in range(n):
            fp.carry(10.0 + (k & 7), [0.0, 0.0, 0.1], G)
            fp.kinematics(q)

    def run_carry_payload(n):
        for k in range(n):
            fp.carry_payload(10.0 + (k & 7), (0.0, 0.0, 1.0))

    def run_kinematics(n):
        for k in range(n):
            q[0] = 0.1 + 1e-4 * (k & 255)
            fp.kinematics(q)

    def run_ramp(n):
        for k in range(n):
            ramping.update(1e-3, 1 + (k >> 10 & 1))      # a new switch every 1024 calls, blending between

    def run_idle(n):
        for _ in range(n):
            idle.update(1e-3, 0)

    t = [0.0]

    def run_cycle(n):
        for _ in range(n):
            t[0] += 1e-3
            comp.cycle(t[0], reading, None, False, False)

    items = {"carry": run_carry, "carry_payload": run_carry_payload, "kinematics": run_kinematics,
             "ramp": run_ramp, "idle": run_idle, "cycle": run_cycle}
    times: dict[str, list[float]] = {k: [] for k in items}
    for f in items.values():
        f(200)
    gc.disable()
    for _ in range(args.blocks):
        for name, f in items.items():
            calls = max(args.calls // 20, 50) if name == "carry" else args.calls
            t0 = time.perf_counter()
            f(calls)
            times[name].append((time.perf_counter() - t0) / calls)
    gc.enable()
    us = {k: round(float(np.median(v)) * 1e6, 2) for k, v in times.items()}
    print(f"{args.blocks} blocks, median of the per-call mean, us:")
    for k, v in us.items():
        print(f"  {k:14s} {v:9.2f} us   {v / us['cycle']:6.3f} x cycle")
    if args.json:
        Path(args.json).write_text(json.dumps({"blocks": args.blocks, "us": us}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
