"""No CMM at all: the robot probes its own part, beside the CMM, the figures of issue 46 (a script, not a test;
`hil_tests/test_hil_probe.py` holds the loop in lock step).

On the paper's circle (config/hil/circle.yaml), starting from examples/too_stiff_reference.yaml (the rotational
compliances 40 % too low), with two truth robots: examples/truth_reference.yaml (the model's kinematics) and
examples/truth_geometric_errors.yaml (the same springs on a DH table 0.2 mm and 0.02 deg off):

1. side by side: cut once (traced, measured by the virtual CMM, probed by the robot itself), learn from the
   probe, from the CMM's points with the part's true frame and from the same placed by --best-fit; cut again
   with each, and with the exact model, the truth's springs on the datasheet's kinematics (mean path error); the
   learned rotational compliances against the truth's;
2. touches: the probe of the same first cut with fewer (or more) touches, three seeds of the repeatability and
   the latency's jitter each, learned and cut again: how many reach 1.2 x the exact model; and the same touches
   without repeatability and jitter (what the places touched do, apart from the probe's noise);
3. speed and latency: the probe at 5 and 50 mm/s with a log that states the latency and one that does not.

    .venv/bin/python benchmarks/bench_probe_part.py [--realtime] [--robot-interface kuka_rsi] [--json FILE]

Lock step by default (the figures do not depend on timing: one run is the figure). ``--robot-interface``: the
side-by-side loop with geometric errors only, each cut through the robot road in real time (`hil.circle.run_circle`).
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

from hil.circle import cut, run_circle
from hil.probe import probe
from hil.report import evaluate_pass
from hil.scenario import load_scenario
from stiffness.data.part_points import read_part
from stiffness.data.probe_log import read_probe
from stiffness.data.trace_file import read_trace
from stiffness.model.prior import Prior
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.part.learn import learn
from stiffness.part.probe import read_probe_against
from stiffness.part.rows import read_against

START = ROOT / "examples" / "too_stiff_reference.yaml"
TRUTHS = {"no geometric errors": ROOT / "examples" / "truth_reference.yaml",
          "geometric errors": ROOT / "examples" / "truth_geometric_errors.yaml"}
TOUCHES = (3, 4, 6, 9, 12, 18, 36, 72, 120, 341)
SEEDS = (17, 18, 19)
EXACT = ROOT / "examples" / "truth_reference.yaml"     # the truth's springs on the datasheet's kinematics: what a
                                                       # perfect stiffness identification gives (no model knows the
                                                       # robot's geometric errors)


def compliance_error(model: StiffnessModel, truth: StiffnessModel) -> tuple[float, float]:
    """Median and largest |relative error| of the rotational compliances (the ones the start has wrong)."""
    labels = model.param_labels()
    rot = [k for k, lab in enumerate(labels) if lab.split(".")[-1][:2] in ("rx", "ry", "rz")]
    rel = np.abs(model.theta[rot] / truth.theta[rot] - 1.0)
    return float(np.median(rel)), float(rel.max())


def learned_from(rows, best_fit: bool = False):
    model = StiffnessModel.from_yaml(START)
    return learn(model, [rows], Prior.catalogue(model, 0.5), best_fit)


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--realtime", action="store_true", help="each cut in real time (processes), not lock step")
    ap.add_argument("--robot-interface", choices=("kuka_rsi", "abb_egm"), default=None,
                    help="only the loop with geometric errors, each cut through the robot road (real time)")
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    t0 = time.monotonic()
    out: dict = {"lockstep": not args.realtime and args.robot_interface is None}
    start = StiffnessModel.from_yaml(START)

    with tempfile.TemporaryDirectory(prefix="stiffcomp-bench-probe-") as tmp:
        w = Path(tmp)
        if args.robot_interface:
            out["road"] = road(w, args.robot_interface, t0)
            return _finish(out, args)

        def again(truth_path, model_path, folder) -> float:
            return cut(load_scenario(), truth_path, model_path, folder, lockstep=not args.realtime).mean_error_mm

        for name, truth_path in TRUTHS.items():
            truth = StiffnessModel.from_yaml(truth_path)
            d = w / name.replace(" ", "_")
            first = cut(load_scenario(), truth_path, START, d / "cut1", d / "cut1.csv", d / "part1.csv",
                        lockstep=not args.realtime, probe_log=d / "probe1.csv")
            trace = read_trace(d / "cut1.csv")
            exact = again(truth_path, EXACT, d / "exact")
            fig = {"first_cut_mm": first.mean_error_mm, "exact_mm": exact,
                   "start_compliances": compliance_error(start, truth)}
            ways = {"probe": (read_probe_against(read_probe(d / "probe1.csv"), trace, start.robot), False),
                    "cmm, true frame": (read_against(read_part(d / "part1.csv"), trace, start.robot), False),
                    "cmm, --best-fit": (read_against(read_part(d / "part1.csv"), trace, start.robot, best_fit=True), True)}
            for k, (way, (rows, best_fit)) in enumerate(ways.items()):
                lrn = learned_from(rows, best_fit)
                path = d / f"learned_{k}.yaml"
                lrn.model.to_yaml(path)
                mean = again(truth_path, path, d / f"cut2_{k}")
                fig[way] = {"mean_mm": mean, "x_exact": mean / exact, "refused": lrn.problems[:1],
                            "rms_before_mm": lrn.before_mm, "rms_after_mm": lrn.after_mm,
                            "compliances": compliance_error(lrn.model, truth)}
                print(f"  {name}: learned from the {way}: next cut {mean:.4f} mm = {mean / exact:.2f} x exact "
                      f"({exact:.4f}){' [refused by part learn: forced here]' if lrn.problems else ''}; "
                      f"RMS {lrn.before_mm:.4f} -> {lrn.after_mm:.4f} mm; rotational compliances off by median "
                      f"{100 * fig[way]['compliances'][0]:.0f} % (start "
                      f"{100 * fig['start_compliances'][0]:.0f} %) ({time.monotonic() - t0:.0f} s)", flush=True)
            out[name] = fig
            if name == "geometric errors":
                out["touches"] = touches(d, truth_path, truth, first, trace, start, exact, again, t0)
                out["speed"] = speed(d, truth_path, truth, first, trace, start, exact, again, t0)
    return _finish(out, args)


def _probe_again(d, truth, first, trace, start, **change):
    """The robot's probe of ``first`` again with the scenario's probe section changed, read and learned."""
    sc = load_scenario()
    for k, v in change.items():
        setattr(sc.probe, k, v)
    world, ev = evaluate_pass(sc, truth, first.result)
    res = probe(sc, world, truth.robot, ev)
    name = "_".join(f"{k}{v}" for k, v in change.items())
    path = res.write(d / f"probe_{name}.csv")
    return learned_from(read_probe_against(read_probe(path), trace, start.robot)), name


def touches(d, truth_path, truth, first, trace, start, exact, again, t0) -> dict:
    out = {}
    for n in TOUCHES:
        ratios = []
        for change in [{"seed": s} for s in SEEDS] + [{"repeatability_mm": 0.0, "latency_jitter_ms": 0.0}]:
            lrn, name = _probe_again(d, truth, first, trace, start, touches=n, **change)
            lrn.model.to_yaml(d / f"l_{name}.yaml")
            ratios.append(again(truth_path, d / f"l_{name}.yaml", d / f"c_{name}") / exact)
        out[n] = {"seeds": ratios[:-1], "noiseless": ratios[-1]}
        print(f"  {n} touches: next cut {', '.join(f'{r:.2f}' for r in ratios[:-1])} x exact (seeds {SEEDS}); "
              f"without repeatability and jitter {ratios[-1]:.2f} x ({time.monotonic() - t0:.0f} s)", flush=True)
    return out


def speed(d, truth_path, truth, first, trace, start, exact, again, t0) -> dict:
    """The probe at 5 and 50 mm/s (latency 1 ms +- 0.5), the log stating the latency or not (0 stated)."""
    out = {}
    for v in (5.0, 50.0):
        for stated in (True, False):
            sc = load_scenario()
            sc.probe.speed_mm_s = v
            world, ev = evaluate_pass(sc, truth, first.result)
            res = probe(sc, world, truth.robot, ev)
            if not stated:
                res.latency_ms = 0.0
            key = f"{v:g} mm/s, latency {'stated' if stated else 'not stated'}"
            path = res.write(d / f"probe_v{v:g}_{stated}.csv")
            lrn = learned_from(read_probe_against(read_probe(path), trace, start.robot))
            lrn.model.to_yaml(d / f"l_v{v:g}_{stated}.yaml")
            ratio = again(truth_path, d / f"l_v{v:g}_{stated}.yaml", d / f"c_v{v:g}_{stated}") / exact
            out[key] = ratio
            print(f"  probe at {key}: next cut {ratio:.2f} x exact ({time.monotonic() - t0:.0f} s)", flush=True)
    return out


def road(w: Path, interface: str, t0: float) -> dict:
    """Cut, probe, learn, cut again through the robot road (real time), the truth with geometric errors."""
    truth_path = TRUTHS["geometric errors"]
    start = StiffnessModel.from_yaml(START)
    sc = load_scenario()
    first = run_circle(sc, truth_path, START, trace=w / "cut1.csv", cmm=w / "part1.csv", probe_log=w / "probe1.csv",
                       robot_interface=interface)
    trace = read_trace(w / "cut1.csv")
    lrn = learned_from(read_probe_against(read_probe(w / "probe1.csv"), trace, start.robot))
    lrn.model.to_yaml(w / "from_probe.yaml")
    cmm = learned_from(read_against(read_part(w / "part1.csv"), trace, start.robot, best_fit=True), best_fit=True)
    cmm.model.to_yaml(w / "from_cmm.yaml")
    fig = {"first_cut_mm": first.summary["mean_error_mm"], "timing": [first.summary["timing"]["exceeded_share"]]}
    for name, model in (("exact", EXACT), ("probe", w / "from_probe.yaml"), ("cmm, --best-fit", w / "from_cmm.yaml")):
        s = run_circle(load_scenario(), truth_path, model, robot_interface=interface).summary
        fig[name] = s["mean_error_mm"]
        fig["timing"].append(s["timing"]["exceeded_share"])
        print(f"  {interface}: the model from the {name}: {s['mean_error_mm']:.4f} mm, late answers "
              f"{s['late_answers']} ({time.monotonic() - t0:.0f} s)", flush=True)
    for name in ("probe", "cmm, --best-fit"):
        fig[f"{name} x exact"] = fig[name] / fig["exact"]
    print(f"  {interface}: probe {fig['probe x exact']:.2f} x exact, CMM (--best-fit) "
          f"{fig['cmm, --best-fit x exact']:.2f} x exact", flush=True)
    return fig


def _finish(out: dict, args) -> dict:
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2, default=float) + "\n")
    return out


if __name__ == "__main__":
    main()
