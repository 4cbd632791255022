"""The cost of a model-ramp cycle against a normal one, and of the cycle that swaps a reload in (a script).

Two cycles of the shipped config (config/default.yaml, its model) run in this process on the same replayed
load: one normal, one inside a model ramp (a same-structure model reloaded with fault_ramp_s long enough
to last the whole run: both predictors run every cycle). They are stepped in alternating blocks, side by
side, with the joints still and with the joints moving (a kinematics pass every cycle, in the ramp two).
Then the swap itself: the cycle that applies a prepared reload (filter, limits, model ramp) against the
cycle before it.

    .venv/bin/python benchmarks/bench_reload.py [--rounds 20] [--block 200] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hil.testing import scaled_model_file, write_config
from plc_link.contract import Command
from service.compensation import load_model
from service.config import load_config
from service.pipeline import Cycle
from service.reload import Prepared, prepare
from service.sources import make_source
from service.sources.replay import write_log
from stiffness.files.yaml_schema import deep_update, dump_yaml, read_yaml

LOAD = np.array([300.0, -200.0, 400.0, 15.0, 10.0, 5.0])
Q0 = np.array([10.0, -80.0, 100.0, 20.0, 40.0, 30.0])


class Bench:
    def __init__(self, folder: Path, name: str):
        log = folder / "ft.blf"
        if not log.exists():
            write_log(log, LOAD + np.random.default_rng(1).standard_normal((4000, 6)))
        self.path = write_config(folder, {"source": {"replay": {"file": str(log), "pacing": "fast", "loop": True}},
                                          "limits": {"fault_ramp_s": 10.0}}, name=name)
        self.cfg = load_config(self.path)
        self.model = load_model(self.cfg)
        self.cycle = Cycle.from_config(self.cfg, self.model)
        self.source = make_source(self.cfg)
        self.k = 0

    def step(self, moving: bool) -> float:
        """One cycle; its work time, s."""
        t = self.k * 1e-3
        q = (Q0 + 2.0 * np.sin(self.k / 200.0)).tolist() if moving else Q0.tolist()
        t0 = time.perf_counter()
        reading, errors = self.source.poll(t)
        self.cycle.step(t, reading, errors, int(Command.ENABLE), self.k & 0xFFFF, q)
        dt = time.perf_counter() - t0
        self.k += 1
        return dt

    def reload_model(self, factor: float, ramp_s: float = 10.0) -> Prepared:
        """A prepared reload of the same model with compliances times ``factor`` (and a new cut-off), ramped
        over ``ramp_s``."""
        model = scaled_model_file(self.cfg.resolve(self.cfg.model.file), factor,
                                  self.path.with_name(f"model_{factor:g}.yaml"))
        cfg = read_yaml(self.path)
        deep_update(cfg, {"model": {"file": str(model)}, "filter": {"cutoff_hz": 50.0 * factor},
                          "limits": {"fault_ramp_s": ramp_s}})
        self.path.write_text(dump_yaml(cfg, sort_keys=False))
        got = prepare(self.cfg, self.model, self.cfg.register_map(), self.cycle)
        assert isinstance(got, Prepared), got
        self.cfg, self.model = got.cfg, got.model
        return got


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rounds", type=int, default=20)
    ap.add_argument("--block", type=int, default=200)
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    out: dict = {"rounds": args.rounds, "block": args.block}
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        normal, ramping = Bench(folder, "normal.yaml"), Bench(folder, "ramping.yaml")
        for b in (normal, ramping):
            for _ in range(500):
                b.step(False)
        ramping.reload_model(1.5).swap(ramping.cycle, ramping.source)
        for moving in (False, True):
            times = {"normal": [], "ramp": []}
            for _ in range(args.rounds):
                times["normal"] += [normal.step(moving) for _ in range(args.block)]
                times["ramp"] += [ramping.step(moving) for _ in range(args.block)]
            assert type(ramping.cycle.compensator.predictor).__name__ == "PredictorRamp", "the ramp ended early"
            med = {k: float(np.median(v)) * 1e6 for k, v in times.items()}
            p99 = {k: float(np.percentile(v, 99)) * 1e6 for k, v in times.items()}
            out["moving" if moving else "still"] = {"median_us": med, "p99_us": p99,
                                                    "ratio_median": med["ramp"] / med["normal"],
                                                    "ratio_p99": p99["ramp"] / p99["normal"],
                                                    "cycles_each": len(times["normal"])}
        # the swap cycle: prepare in this (main) thread, apply inside the timed cycle, against the cycle before
        swap, before = [], []
        for r in range(args.rounds):
            prepared = normal.reload_model(1.0 + 0.1 * (r + 1), ramp_s=0.005)
            for _ in range(20):                 # the last ramp (5 cycles) has ended
                normal.step(True)
            before.append(normal.step(True))
            t0 = time.perf_counter()
            prepared.swap(normal.cycle, normal.source)
            swap.append(time.perf_counter() - t0 + normal.step(True))
        out["swap_cycle"] = {"median_us": float(np.median(swap)) * 1e6, "before_median_us": float(np.median(before)) * 1e6,
                             "ratio_median": float(np.median(swap) / np.median(before)), "runs": len(swap)}
        for b in (normal, ramping):
            b.source.close()
    print(json.dumps(out, indent=2))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
