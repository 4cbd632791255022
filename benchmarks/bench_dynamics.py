"""The dynamic compensation in the HIL, the figures of issue 26 (a script, not a test; `hil_tests/test_hil_dynamics.py`
holds the Done-when cases in lock step).

On the paper's circle (config/hil/circle.yaml) with the ringing robot stub (10 Hz and 16 Hz, 3 %), per extra
delay of the PLC: the uncompensated and the static pass once, the modes identified from the uncompensated
pass (`hil.dynamics`, as `stiffcomp modes` does) and the delay measured on the static one; then one dynamic
pass per variant: the modes as identified or with their frequencies off by ``--mode-error``, the modal
filter exact or with ``--added-damping``, with and without the feedforward. Printed per variant: the peak
path error in the entry and exit windows and the steady mean, against the static pass's (ratios).

    .venv/bin/python benchmarks/bench_dynamics.py [--extra-delay-ms 0 8] [--mode-error 0 0.2 -0.2]
                                                  [--added-damping 0 0.3] [--feedforward] [--realtime] [--json FILE]

Lock step by default (deterministic: one run is the figure); ``--realtime`` runs the passes as processes in real
time (then repeat it: the figures vary with the host's load).
"""

from __future__ import annotations

import argparse
import copy
import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hil.circle import evaluate_pass
from hil.dynamics import DynamicOptions, identify_from_pass, service_dynamics
from hil.lockstep import run_lockstep
from hil.report import end_to_end_delay, errors, window_errors
from hil.run import run_pass
from hil.scenario import load_scenario
from hil.world import World
from stiffness.model import StiffnessModel


def figures(world, ev) -> dict:
    w = window_errors(world, ev)
    mean, worst = errors(ev)
    return {"entry_peak_mm": w["entry_peak_mm"], "exit_peak_mm": w["exit_peak_mm"],
            "steady_mean_mm": w["steady_mean_mm"], "mean_error_mm": mean, "max_error_mm": worst}


def one(args, sc, truth, model_path, folder: Path, compensate: bool, overrides=None):
    """One pass (lock step, or real time with --realtime) and its evaluation."""
    if args.realtime:
        r = run_pass(sc, truth, model_path, compensate, folder, service_overrides=overrides)
    else:
        r = run_lockstep(sc, truth, model_path, compensate, folder, overrides)
    return r, evaluate_pass(sc, truth, r)[1]


def run(args) -> list[dict]:
    truth = StiffnessModel.from_yaml(Path(args.truth))
    model = Path(args.model) if args.model else None
    rows = []
    found = None
    for extra in args.extra_delay_ms:
        sc = load_scenario(args.scenario)
        sc.plc.extra_delay_ms = extra
        model_path = model or sc.resolve(sc.model)
        world = World(sc, truth.robot)
        with tempfile.TemporaryDirectory(prefix="bench-dynamics-") as tmp:
            tmp = Path(tmp)

            if found is None:
                found = identify_from_pass(sc, truth, DynamicOptions())
                print(f"identified: {found.to_config()} (explains {100 * found.explained:.2f} % of the "
                      f"deflection; the static fit {100 * found.explained_static:.2f} %)", flush=True)
            _, unc = one(args, sc, truth, model_path, tmp / "uncompensated", False)
            static_pass, static = one(args, sc, truth, model_path, tmp / "static", True)
            delay_ms = 1000.0 * (end_to_end_delay(world, static_pass.log) or 0.0)
            base = {"extra_delay_ms": extra, "delay_ms": round(delay_ms, 2),
                    "uncompensated": figures(world, unc), "static": figures(world, static)}
            print(f"\nextra delay {extra:g} ms: measured end-to-end delay {delay_ms:.2f} ms; static: entry "
                  f"{base['static']['entry_peak_mm']:.4f}, exit {base['static']['exit_peak_mm']:.4f}, steady mean "
                  f"{base['static']['steady_mean_mm']:.4f} mm (uncompensated mean "
                  f"{base['uncompensated']['mean_error_mm']:.3f} mm)", flush=True)
            print(f"{'mode error':>10} {'damping+':>8} {'ff':>3} | {'entry mm':>8} {'ratio':>6} | {'exit mm':>8} "
                  f"{'ratio':>6} | {'steady':>7} {'static':>7} | {'mean':>7}", flush=True)
            for ff in ([False, True] if args.feedforward else [False]):
                for zeta in args.added_damping:
                    for err in args.mode_error:
                        opts = DynamicOptions(err, zeta, ff)
                        over = service_dynamics(found, delay_ms, opts, sc, world, tmp / "plan")
                        _, dyn = one(args, sc, truth, model_path, tmp / "dynamic", True, copy.deepcopy(over))
                        f = figures(world, dyn)
                        s = base["static"]
                        row = {**base, "mode_error": err, "added_damping": zeta, "feedforward": ff, "dynamic": f,
                               "entry_ratio": f["entry_peak_mm"] / s["entry_peak_mm"],
                               "exit_ratio": f["exit_peak_mm"] / s["exit_peak_mm"]}
                        rows.append(row)
                        print(f"{err:>+10.2f} {zeta:>8.2f} {'yes' if ff else 'no':>3} | {f['entry_peak_mm']:8.4f} "
                              f"{row['entry_ratio']:6.0%} | {f['exit_peak_mm']:8.4f} {row['exit_ratio']:6.0%} | "
                              f"{f['steady_mean_mm']:7.4f} {s['steady_mean_mm']:7.4f} | {f['mean_error_mm']:7.4f}",
                              flush=True)
    return rows


def main(argv: list[str] | None = None) -> list[dict]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default=None)
    ap.add_argument("--truth", default=str(ROOT / "examples" / "truth_reference.yaml"))
    ap.add_argument("--model", default=None, help="the service's model (default: the scenario's)")
    ap.add_argument("--extra-delay-ms", type=float, nargs="+", default=[0.0, 8.0])
    ap.add_argument("--mode-error", type=float, nargs="+", default=[0.0, 0.2, -0.2])
    ap.add_argument("--added-damping", type=float, nargs="+", default=[0.0, 0.3])
    ap.add_argument("--feedforward", action="store_true", help="each variant also with the feedforward")
    ap.add_argument("--realtime", action="store_true", help="the passes in real time, not in lock step")
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    rows = run(args)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    return rows


if __name__ == "__main__":
    main()
