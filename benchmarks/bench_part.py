"""Learn from the part in the HIL, the figures of issue 29 (a script, not a test; `hil_tests/test_hil_part.py`
holds the same loop in lock step).

On the paper's circle (config/hil/circle.yaml) with examples/truth_reference.yaml as the robot:

1. learn: cut once with a model whose rotational compliances are 40 % too low (traced, measured by the
   virtual CMM), `part learn`, cut again; against the exact model's cut;
2. two places: cut at A and at B with the same start, learn from both, cut a third circle C with the learned,
   the exact and the start model;
3. a hidden effect: a truth with hysteresis at joint 1 (0.012 deg) cut with the exact springs, `part diagnose`;
   and the control, the truth without it.

    .venv/bin/python benchmarks/bench_part.py [--lockstep] [--road kuka_rsi|abb_egm] [--learn-only]
                                              [--plot FILE] [--json FILE]

Real time by default (each cut is a service, a virtual sensor and a virtual PLC in processes of their own);
the timing verdict of every cut is printed, since a busy host makes the compensated figures worse.
``--road``: every cut through that robot road (a virtual KUKA RSI or ABB EGM robot in the PLC's place, real
time only), and the first cut's part error as `part compare` reads it from the trace the road left beside the
HIL's (issue 43). ``--learn-only``: step 1 alone.
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

from hil.circle import cut, timing_verdict
from hil.scenario import load_scenario
from hil.testing import ROTATIONAL, scaled_model_file
from stiffness.data.part_points import read_part
from stiffness.data.trace_file import read_trace
from stiffness.effects.hysteresis import Hysteresis
from stiffness.model.prior import Prior
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.part.diagnose import diagnose_parts
from stiffness.part.learn import learn
from stiffness.part.rows import read_against

TRUTH = ROOT / "examples" / "truth_reference.yaml"
PLACES = {"A": [0.0, -60.0, 90.0, 0.0, 60.0, 0.0], "B": [25.0, -45.0, 75.0, 0.0, 60.0, 30.0],
          "C": [-20.0, -70.0, 100.0, 0.0, 60.0, -20.0]}


def scenario(place: str):
    sc = load_scenario()
    sc.circle.center_q_deg = list(PLACES[place])
    return sc


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--lockstep", action="store_true", help="each cut in lock step (deterministic, no real time)")
    ap.add_argument("--plot", default=None, metavar="FILE", help="the part error before and after learning (PNG)")
    ap.add_argument("--json", default=None, metavar="FILE")
    ap.add_argument("--road", default=None, choices=["kuka_rsi", "abb_egm"],
                    help="every cut through this robot road instead of the PLC's (real time)")
    ap.add_argument("--learn-only", action="store_true", help="step 1 alone (cut, learn, cut again, exact)")
    args = ap.parse_args(argv)
    if args.road and args.lockstep:
        ap.error("the robot road runs on the robot's clock, in real time only: --road without --lockstep")
    t0 = time.monotonic()
    verdicts = []

    def run(place, truth, model, folder, traced=False):
        c = cut(scenario(place), truth, model, folder, folder / "trace.csv" if traced else None,
                folder / "part.csv" if traced else None, lockstep=args.lockstep, robot_interface=args.road)
        s = c.result.stats[-1]
        verdicts.append(timing_verdict(int(s.get("cycles", 0)), int(s.get("exceed_count", 0)))["exceeded_share"])
        print(f"  cut {place} with {Path(model).stem}: mean path error {c.mean_error_mm:.4f} mm, part error "
              f"{c.part.part_error_mm:.4f} mm ({time.monotonic() - t0:.0f} s)", flush=True)
        return c

    with tempfile.TemporaryDirectory(prefix="stiffcomp-bench-part-") as tmp:
        w = Path(tmp)
        start = scaled_model_file(TRUTH, 0.6, w / "start.yaml", keys=ROTATIONAL)     # 40 % too stiff
        model = StiffnessModel.from_yaml(start)
        prior = Prior.catalogue(model, 0.5)
        first = {p: run(p, TRUTH, start, w / f"{p}_start", traced=True) for p in ("A",) + (() if args.learn_only else ("B",))}
        rows = {p: read_against(read_part(w / f"{p}_start" / "part.csv"), read_trace(w / f"{p}_start" / "trace.csv"),
                                model.robot, f"part {p}") for p in first}
        compared = float(np.mean(np.abs(rows["A"].nominal_mm)))     # what `part compare` gives for part A
        one = learn(model, [rows["A"]], prior)
        one.model.to_yaml(w / "learned_A.yaml")
        again = run("A", TRUTH, w / "learned_A.yaml", w / "A_learned")
        exact_a = run("A", TRUTH, TRUTH, w / "A_exact")
        at_c, diag, two = {}, {}, None
        if not args.learn_only:
            two = learn(model, [rows["A"], rows["B"]], prior)
            two.model.to_yaml(w / "learned_AB.yaml")
            at_c = {name: run("C", TRUTH, path, w / f"C_{name}").mean_error_mm for name, path in
                    (("learned from A and B", w / "learned_AB.yaml"), ("exact", TRUTH), ("start", start))}
        for name, hidden in () if args.learn_only else ((f"{Hysteresis.name} at joint 1", True), ("control", False)):
            truth = StiffnessModel.from_yaml(TRUTH)
            if hidden:
                d = truth.to_dict()
                d["effects"].append({"effect": Hysteresis.name, "joint": 1, "offset_deg": 0.012})
                truth = StiffnessModel.from_dict(d, f"truth + {Hysteresis.name}", robot=truth.robot)
            tp = w / f"truth_{hidden}.yaml"
            truth.to_yaml(tp)
            run("A", tp, TRUTH, w / f"D_{hidden}", traced=True)
            exact = StiffnessModel.from_yaml(TRUTH)
            r = read_against(read_part(w / f"D_{hidden}" / "part.csv"), read_trace(w / f"D_{hidden}" / "trace.csv"),
                             exact.robot)
            pd = diagnose_parts(exact, [r], Prior.catalogue(exact, 0.5))
            best = pd.diagnosis.best
            diag[name] = {"named": None if best is None else f"{best.name} at joint {best.joint}",
                          "verdict": pd.diagnosis.verdict, "message": pd.message}
        if args.plot:
            plot(first["A"], again, exact_a, Path(args.plot))
    out = {"mode": "lock step" if args.lockstep else "real time", "road": args.road or "plc",
           "learn": {"start_mm": first["A"].mean_error_mm, "learned_mm": again.mean_error_mm,
                     "exact_mm": exact_a.mean_error_mm, "ratio_to_exact": again.mean_error_mm / exact_a.mean_error_mm,
                     "part_error_before_mm": first["A"].part.part_error_mm, "part_error_after_mm": again.part.part_error_mm,
                     "part_compare_before_mm": compared,
                     "part_compare_to_hil": compared / first["A"].part.part_error_mm,
                     "compliance_changes": [[name, after / before] for name, before, after in one.changes[:5]
                                            if before > 0],
                     "determined": len(one.determined), "problems": list(one.problems)},
           "exceeded_share_max": max(verdicts), "seconds": time.monotonic() - t0}
    if two is not None:
        out["third_place"] = {**at_c, "ratio_to_exact": at_c["learned from A and B"] / at_c["exact"],
                              "determined": len(two.determined)}
        out["diagnose"] = diag
    print(json.dumps(out, indent=2))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return out


def plot(before, after, exact, path: Path) -> None:
    """The part error around the contour (the virtual CMM) before and after learning, and the exact model's."""
    from matplotlib.figure import Figure

    from stiffness.report.plots import legend_below

    fig = Figure(figsize=(11, 4.8), layout="constrained")
    ax = fig.add_subplot()
    for c, label, colour in ((before, "cut with the too-stiff model", "tab:red"),
                             (after, "cut again with the model learned from that part", "tab:blue"),
                             (exact, "the exact model's cut", "k")):
        ax.plot(np.degrees(c.part.angle), c.part.error_mm, color=colour, lw=1.0,
                label=f"{label}: mean |error| {c.part.part_error_mm:.4f} mm")
    ax.axhline(0.0, color="k", lw=0.4)
    ax.set_xlabel("angle along the circle, deg")
    ax.set_ylabel("part error (virtual CMM), mm")
    ax.set_title("The paper's circle: the part error before and after learning from one part")
    ax.grid(alpha=0.3)
    legend_below(fig, ax, ncols=1)
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
