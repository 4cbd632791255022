"""The cycle's work with the dynamic compensation against the static path (a script, not a test).

One whole `service.pipeline.Cycle.step` per cycle as `bench_effects.py` drives it (a moving robot under a
milling load, a new sample and new joints every cycle), on config/models/kr125_6dof.yaml: the static path
(``dynamics`` off), each part of the dynamic compensation alone (the predictor, the structure's two modes,
the feedforward from a plan file, the PLC's program time fed every cycle), all three, and the structure's
modes with the accelerometer's observer (a new value every cycle; against "structure", the force-only
dynamic path it corrects), and the same with the box's values replayed from a file (`accelerometer.replay`, a
new sample every cycle; against "observer", the PLC's values), and the observer with its follower
(``follow``: its bank of candidates each cycle, in Python after the cycle). Each runs on the
Python path and on the compiled one, in alternating blocks of cycles in one process (the machine's drift
falls on all alike); the figure is the ratio of the medians of the per-block mean cycle times to the static
path's on the same path.

    .venv/bin/python benchmarks/bench_dynamics_cost.py [--blocks 30] [--cycles 1000] [--json FILE]
"""

from __future__ import annotations

import argparse
import gc
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hil.testing import model_with
from plc_link.contract import FROM_PLC, Command, FromPlc
from service.ati import Reading
from service.config import ServiceConfig, load_config
from service.pipeline import Cycle

MODES = [{"hz": 10.0, "damping": 0.03, "direction": [1.0, 0.0, 0.0]},
         {"hz": 16.0, "damping": 0.03, "direction": [0.0, 1.0, 0.0]}]


REPLAYED = "observer, replay"      # the observer's row with the box's values from a file


def sections(plan: Path) -> dict[str, dict | None]:
    ff = {"source": "file", "file": str(plan)}
    observer = {"structure": {"modes": MODES, "lag_ms": 8.0}, "observer": {"modes": MODES, "horizon_ms": 4.0}}
    follower = {"structure": observer["structure"], "observer": {**observer["observer"], "follow": True}}
    return {"static": None, "predictor": {"predictor": {}}, "structure": {"structure": {"modes": MODES, "lag_ms": 8.0}},
            "feedforward": {"feedforward": ff},
            "all three": {"predictor": {}, "structure": {"modes": MODES, "lag_ms": 8.0}, "feedforward": ff},
            "observer": observer, REPLAYED: observer, "observer, follow": follower}


def config(section: dict | None, box: Path | None = None) -> ServiceConfig:
    """The shipped config with ``dynamics`` set to ``section``; ``box``: the accelerometer's values replayed
    from this file (else from the PLC's record)."""
    cfg = load_config(ROOT / "config" / "default.yaml")
    if section is None:
        return cfg
    data = cfg.model_dump()
    data["dynamics"] = {"enabled": True, "delay_ms": 16.0, **section}
    if "observer" in section:                       # the accelerometer it reads, a new value every cycle
        data["accelerometer"] = {"enabled": True, **({"replay": str(box)} if box is not None else {})}
    out = ServiceConfig.model_validate(data)
    out.path = cfg.path
    return out


class Runner:
    def __init__(self, cfg: ServiceConfig, compiled: bool):
        self.cycle = Cycle.from_config(cfg, model_with(base="kr125_6dof"))
        if compiled:
            self.cycle.compensator.compile()
        rng = np.random.default_rng(1)
        phase = np.linspace(0, 8 * np.pi, 4096)
        self.w = [[300 * np.cos(p) + 5 * a, 300 * np.sin(p) + 5 * b, 150.0 + 5 * c, 20 * np.sin(p), 20 * np.cos(p), 1.0]
                  for p, a, b, c in zip(phase, *rng.standard_normal((3, 4096)))]
        self.q = [[10 + 2 * np.sin(p), -70 + np.cos(p), 95.0, 15.0, 40 + np.sin(p), -20.0] for p in phase]
        self.inputs = FromPlc(**{v.name: 0.0 for v in FROM_PLC})
        self.t, self.k = 0.0, 0

    def run(self, cycles: int) -> float:
        step, enable, clock, inp = self.cycle.step, int(Command.ENABLE), time.perf_counter, self.inputs
        t0 = clock()
        for _ in range(cycles):
            self.t += 0.001
            self.k += 1
            i = self.k & 4095
            step(self.t, Reading(self.w[i], 0, self.k, False), [], enable, self.k, self.q[i], inputs=inp._replace(
                plan_time_s=self.t % 60.0, acc_x=0.01 * self.w[i][0], acc_z=9.81, acc_samples=self.k & 0xFFFF))
        return (clock() - t0) / cycles


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=30)
    ap.add_argument("--cycles", type=int, default=1000)
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    with tempfile.TemporaryDirectory() as tmp:
        plan = Path(tmp) / "plan.csv"
        t = np.arange(0.0, 61.0, 0.001)
        e = np.clip((t % 2.0 - 0.5) / 0.1, 0.0, 1.0) * (t % 2.0 < 1.5)
        np.savetxt(plan, np.column_stack([t, e, np.tile([300.0, -200.0, 150.0], (len(t), 1))]), delimiter=",",
                   header="t_s,engagement,fx_N,fy_N,fz_N", comments="", fmt="%.4f")
        box = Path(tmp) / "box.csv"                 # a sample every ms, as the PLC's record gives one every cycle
        np.savetxt(box, np.column_stack([t, 3.0 * np.sin(60.0 * t), np.zeros_like(t), np.full_like(t, 9.81)]), delimiter=",",
                   header="t_s,acc_x,acc_y,acc_z", comments="", fmt="%.4f")
        runners = {(name, c): Runner(config(sec, box if name == REPLAYED else None), c)
                   for name, sec in sections(plan).items() for c in (False, True)}
        means: dict[tuple, list[float]] = {k: [] for k in runners}
        for r in runners.values():
            r.run(200)                                    # warm-up
        gc.collect()
        for _ in range(args.blocks):
            for k, r in runners.items():
                means[k].append(r.run(args.cycles))
    med = {k: float(np.median(v)) for k, v in means.items()}
    out = {}
    print(f"{args.blocks} blocks of {args.cycles} cycles each, alternating; median of the block means")
    print(f"{'':<18} {'Python us':>10} {'x static':>9} {'compiled us':>12} {'x static':>9}")
    for name in sections(Path()):
        py, cc = med[(name, False)], med[(name, True)]
        out[name] = {"python_us": 1e6 * py, "compiled_us": 1e6 * cc, "python_x_static": py / med[("static", False)],
                     "compiled_x_static": cc / med[("static", True)]}
        print(f"{name:<18} {1e6 * py:10.1f} {out[name]['python_x_static']:9.2f} {1e6 * cc:12.1f} "
              f"{out[name]['compiled_x_static']:9.2f}")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
