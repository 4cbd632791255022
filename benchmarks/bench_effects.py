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

Each model runs twice in the same alternation: on the Python path (the reference) and on the compiled one
(`service.kernel`, what the service runs), so the table shows both and their ratio from one run. The C
reference loop's work (`bench_cycle.C_WORK`, ~10,000 multiply-adds, compiled now with the system's C
compiler) runs in the same alternation, each cycle timed in C, so "x C" is the ratio of p50s measured side
by side (the issue's target: <= 4 for the every-effect cycle with an identified preload).

    .venv/bin/python benchmarks/bench_effects.py [--blocks 30] [--cycles 1000] [--json FILE]
"""

from __future__ import annotations

import argparse
import ctypes
import gc
import json
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hil.testing import BEYOND_SPRINGS, model_with
from plc_link.contract import Command
from service.ati import Reading
from service.config import load_config
from service.pipeline import Cycle
from stiffness.kinematics.robot import load_robot
from stiffness.model.stiffness_model import StiffnessModel

C_BLOCK = r"""
#include <time.h>
static double now(void) { struct timespec t; clock_gettime(CLOCK_MONOTONIC, &t); return t.tv_sec + t.tv_nsec * 1e-9; }
void block(int n, double *exec) {
    volatile double acc = 0.0; double a[100], b[100];
    for (int i = 0; i < 100; i++) { a[i] = i * 0.5; b[i] = 1.0 / (i + 1); }
    for (int k = 0; k < n; k++) { double start = now(); C_WORK exec[k] = now() - start; }
}
"""


class CReference:
    """The C loop's work per cycle, timed in C (None without a C compiler)."""

    def __init__(self, folder: Path):
        from bench_cycle import C_WORK

        cc = shutil.which("cc") or shutil.which("gcc")
        src, lib = folder / "ref_block.c", folder / "ref_block.so"
        src.write_text(C_BLOCK.replace("C_WORK", C_WORK))
        subprocess.run([cc, "-O2", "-shared", "-fPIC", "-o", str(lib), str(src)], check=True)
        self.lib = ctypes.CDLL(str(lib))
        self.samples: list[float] = []

    def run(self, cycles: int) -> float:
        exec_s = (ctypes.c_double * cycles)()
        self.lib.block(cycles, exec_s)
        self.samples.extend(exec_s)
        return sum(exec_s) / cycles


class Runner:
    """One model's cycle, driven like a moving robot under a milling load."""

    def __init__(self, m: StiffnessModel, compiled: bool = False):
        cfg = load_config(ROOT / "config" / "default.yaml")
        self.cycle = Cycle.from_config(cfg, m)
        if compiled:
            self.cycle.compensator.compile()
        self.t = 0.0
        self.k = 0
        rng = np.random.default_rng(1)
        n = 4096
        phase = np.linspace(0, 8 * np.pi, n)
        self.w = [[300 * np.cos(p) + 5 * a, 300 * np.sin(p) + 5 * b, 150.0 + 5 * c, 20 * np.sin(p), 20 * np.cos(p), 1.0]
                  for p, a, b, c in zip(phase, *rng.standard_normal((3, n)))]
        self.q = [[10 + 2 * np.sin(p), -70 + np.cos(p), 95.0, 15.0, 40 + np.sin(p), -20.0] for p in phase]

        self.samples: list[float] = []             # every timed cycle, s

    def run(self, cycles: int) -> float:
        """Mean seconds per cycle over ``cycles`` cycles (each cycle's time kept in ``samples``)."""
        step, enable, clock = self.cycle.step, int(Command.ENABLE), time.perf_counter
        out = self.samples
        t0 = t_prev = clock()
        for _ in range(cycles):
            self.t += 0.001
            self.k += 1
            i = self.k & 4095
            step(self.t, Reading(self.w[i], 0, self.k, False), [], enable, self.k, self.q[i])
            t = clock()
            out.append(t - t_prev)
            t_prev = t
        return (t_prev - t0) / cycles


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
    identified["preload"] = [{"joint": 2, "my2_kgm": -40.0, "my3_kgm": 30.0}, {"joint": 3, "mx3_kgm": 12.0}]
    models["every effect, preload identified"] = StiffnessModel.from_dict(
        identified, "every effect, preload identified", robot=every.robot)
    runners = {(k, c): Runner(m, c) for k, m in models.items() for c in (False, True)}
    tmp = tempfile.TemporaryDirectory()
    ref = CReference(Path(tmp.name)) if shutil.which("cc") or shutil.which("gcc") else None
    if ref is not None:
        runners[("C reference", True)] = ref
    for r in runners.values():
        r.run(200)                                            # warm up
        r.samples.clear()
    times: dict[str, list[float]] = {k: [] for k in runners}
    gc.disable()
    try:
        for _ in range(args.blocks):
            for k, r in runners.items():
                times[k].append(r.run(args.cycles))
    finally:
        gc.enable()
    tmp.cleanup()
    med = {k: float(np.median(v)) for k, v in times.items()}
    pct = {k: np.percentile(r.samples, [50, 99]) * 1e6 for k, r in runners.items()}
    c50 = pct[("C reference", True)][0] if ref is not None else float("nan")
    out = {k: {"python_us": med[(k, False)] * 1e6, "compiled_us": med[(k, True)] * 1e6,
               "python_p50_us": pct[(k, False)][0], "python_p99_us": pct[(k, False)][1],
               "compiled_p50_us": pct[(k, True)][0], "compiled_p99_us": pct[(k, True)][1],
               "ratio": med[(k, False)] / med[("springs only", False)],
               "compiled_ratio": med[(k, True)] / med[("springs only", True)],
               "speedup": med[(k, False)] / med[(k, True)],
               "python_x_c": pct[(k, False)][0] / c50, "compiled_x_c": pct[(k, True)][0] / c50} for k in models}
    if ref is not None:
        out["C reference"] = {"p50_us": float(c50), "p99_us": float(pct[("C reference", True)][1])}
    w = max(len(k) for k in models)
    print(f"cycle work per cycle, {args.blocks} alternating blocks of {args.cycles} cycles: p50 / p99 (µs), x C = p50 "
          f"over the C loop's p50 ({c50:.1f} µs)")
    print(f"{'model':<{w}}  {'Python p50/p99':>15}  {'x C':>5}  {'compiled p50/p99':>16}  {'x C':>5}  speed-up")
    for k in models:
        v = out[k]
        print(f"{k:<{w}}  {v['python_p50_us']:6.1f} / {v['python_p99_us']:6.1f}  {v['python_x_c']:5.1f}  "
              f"{v['compiled_p50_us']:7.1f} / {v['compiled_p99_us']:6.1f}  {v['compiled_x_c']:5.1f}  {v['speedup']:5.1f}x")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
