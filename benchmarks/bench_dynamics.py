"""The dynamic compensation in the HIL, the figures of issue 26 (a script, not a test; `hil_tests/test_hil_dynamics.py`
holds the Done-when cases in lock step).

On the paper's circle (config/hil/circle.yaml) with the ringing robot stub (10 Hz and 16 Hz, 3 %), per extra
delay of the PLC: the uncompensated and the static pass once, the modes identified from the uncompensated
pass (`hil.dynamics`, as `stiffcomp modes` does) and the delay measured on the static one; then one dynamic
pass per variant: the modes as identified or with their frequencies off by ``--mode-error``, the modal
filter exact or with ``--added-damping``, with and without the feedforward, with and without the
accelerometer's observer (``--observer``: the virtual box on in every pass, docs/accelerometer.md); ``--learned``:
the service's model learned first from one part (a cut with it, the virtual CMM, `part learn`). Printed per
variant: the peak path error in the entry and exit windows and the steady mean, against the static pass's
(ratios).

    .venv/bin/python benchmarks/bench_dynamics.py [--extra-delay-ms 0 8] [--mode-error 0 0.2 -0.2]
                                                  [--added-damping 0 0.3] [--feedforward] [--observer]
                                                  [--learned]
                                                  [--realtime] [--json FILE]

Lock step by default (deterministic: one run is the figure); ``--realtime`` runs the passes as processes in real
time (then repeat it: the figures vary with the host's load).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hil.dynamics import DynamicOptions, compare
from hil.lockstep import run_lockstep
from hil.run import run_pass
from hil.scenario import load_scenario
from stiffness.model.stiffness_model import StiffnessModel


def realtime(sc, truth, model_path, compensate, folder, overrides=None):
    return run_pass(sc, truth, model_path, compensate, folder, service_overrides=overrides)


def table(result: dict) -> None:
    u = result["uncompensated"]
    print(f"uncompensated: mean {u['mean_error_mm']:.3f} mm, entry {u['entry_peak_mm']:.3f}, exit "
          f"{u['exit_peak_mm']:.3f} mm")
    for case in result["cases"]:
        s = case["static"]
        print(f"\nextra delay {case['extra_delay_ms']:g} ms: measured end-to-end delay {case['delay_ms']:.2f} ms; "
              f"static: entry {s['entry_peak_mm']:.4f}, exit {s['exit_peak_mm']:.4f}, steady mean "
              f"{s['steady_mean_mm']:.4f}, mean {s['mean_error_mm']:.4f} mm")
        print(f"{'mode error':>10} {'damping+':>8} {'ff':>3} {'obs':>3} | {'entry mm':>8} {'ratio':>6} | {'exit mm':>8} "
              f"{'ratio':>6} | {'steady':>7} {'static':>7} | {'mean':>7}")
        for row in case["dynamic"]:
            o, f = row["options"], row["figures"]
            print(f"{o.mode_error:>+10.2f} {o.added_damping:>8.2f} {'yes' if o.feedforward else 'no':>3} "
                  f"{'yes' if o.observer else 'no':>3} | "
                  f"{f['entry_peak_mm']:8.4f} {row['entry_ratio']:6.0%} | {f['exit_peak_mm']:8.4f} "
                  f"{row['exit_ratio']:6.0%} | {f['steady_mean_mm']:7.4f} {s['steady_mean_mm']:7.4f} | "
                  f"{f['mean_error_mm']:7.4f}")


def learned_from_a_part(sc, truth_path: Path, model_path: Path, folder: Path) -> Path:
    """The model `part learn` gives from one lock-step cut with ``model_path`` (traced, the virtual CMM's part)."""
    from hil.circle import cut
    from stiffness.data.part_points import read_part
    from stiffness.data.trace_file import read_trace
    from stiffness.model.prior import Prior
    from stiffness.part.learn import learn
    from stiffness.part.rows import read_against

    first = cut(sc, truth_path, model_path, folder / "first", folder / "trace.csv", folder / "part.csv", lockstep=True)
    model = StiffnessModel.from_yaml(model_path)
    rows = read_against(read_part(folder / "part.csv"), read_trace(folder / "trace.csv"), model.robot, "part")
    learn(model, [rows], Prior.catalogue(model, 0.5)).model.to_yaml(folder / "learned.yaml")
    print(f"learned from one part: the first cut's mean path error {first.mean_error_mm:.4f} mm", file=sys.stderr)
    return folder / "learned.yaml"


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default=None)
    ap.add_argument("--truth", default=str(ROOT / "examples" / "truth_reference.yaml"))
    ap.add_argument("--model", default=None, help="the service's model (default: the scenario's)")
    ap.add_argument("--learned", action="store_true",
                    help="first learn the service's model from one part: a lock-step cut with it, traced and "
                         "measured by the virtual CMM, and `part learn` (docs/accelerometer.md)")
    ap.add_argument("--extra-delay-ms", type=float, nargs="+", default=[0.0, 8.0])
    ap.add_argument("--mode-error", type=float, nargs="+", default=[0.0, 0.2, -0.2])
    ap.add_argument("--added-damping", type=float, nargs="+", default=[0.0, 0.1])
    ap.add_argument("--feedforward", action="store_true", help="each variant also with the feedforward")
    ap.add_argument("--observer", action="store_true",
                    help="each variant also with the accelerometer's observer (dynamics.observer)")
    ap.add_argument("--observer-horizon-ms", type=float, default=None,
                    help="dynamics.observer.horizon_ms (default: 5 PLC cycles plus the extra delay, at most 7)")
    ap.add_argument("--observer-band-hz", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                    help="dynamics.observer.band_hz (default: the observer's own)")
    ap.add_argument("--follow", action="store_true",
                    help="the observer follows the modes' frequencies in the cut (dynamics.observer.follow)")
    ap.add_argument("--commissioning", choices=("tap", "cut"), default="tap")
    ap.add_argument("--predictor-hz", type=float, default=None, help="dynamics.predictor.bandwidth_hz")
    ap.add_argument("--realtime", action="store_true", help="the passes in real time, not in lock step")
    ap.add_argument("--plc-period-ms", type=float, default=None,
                    help="the PLC's task cycle (default: the scenario's; hil_tests/test_hil_dynamics.py runs the "
                         "library's own 1 ms)")
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    sc = load_scenario(args.scenario)
    if args.plc_period_ms is not None:
        sc.plc.period_ms = args.plc_period_ms
    truth = StiffnessModel.from_yaml(Path(args.truth))
    model_path = Path(args.model) if args.model else sc.resolve(sc.model)
    if args.learned:            # the learned model's folder lives until the passes that read it are done
        keep = tempfile.TemporaryDirectory(prefix="stiffcomp-bench-dynamics-")
        model_path = learned_from_a_part(sc, Path(args.truth), model_path, Path(keep.name))
    variants = [DynamicOptions(err, zeta, ff, commissioning=args.commissioning, predictor_hz=args.predictor_hz,
                               observer=obs, observer_horizon_ms=args.observer_horizon_ms,
                               observer_band_hz=args.observer_band_hz, follow=args.follow)
                for obs in ([False, True] if args.observer else [False])
                for ff in ([False, True] if args.feedforward else [False])
                for zeta in args.added_damping for err in args.mode_error]
    result = compare(sc, truth, model_path, [(extra, variants) for extra in args.extra_delay_ms],
                     run=realtime if args.realtime else run_lockstep,
                     progress=lambda text: print(text, file=sys.stderr, flush=True))
    print(f"identified ({args.commissioning}): {result['identified']}")
    table(result)
    if args.json:
        for case in result["cases"]:
            for row in case["dynamic"]:
                row["options"] = dataclasses.asdict(row["options"])
        Path(args.json).write_text(json.dumps(result, indent=2, default=str) + "\n")
    return result


if __name__ == "__main__":
    main()
