"""The preloaded backlash in the HIL: mean path errors without compensation, with the preload-aware and
with the preload-blind model (a script, not a test; docs/hil.md, "Preloaded backlash").

Each run mills the circle of `hil.preload` once per model in real time, the service, the virtual sensor
and the virtual PLC in their own processes (`hil.preload.preload_path_errors`); the uncompensated error
is the truth's deflection along the nominal path. Prints the three mean path errors per run, the
aware and blind errors as shares of the uncompensated one, and the timing verdict of each pass.

    .venv/bin/python benchmarks/bench_hil_preload.py [--runs 3] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> int:
    from hil.circle import timing_verdict
    from hil.preload import preload_path_errors

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    runs = []
    print(f"{'run':<4} {'uncompensated':>14} {'aware':>16} {'blind':>16}   mm, mean |radial error| over the cut")
    for k in range(args.runs):
        with tempfile.TemporaryDirectory(prefix="stiffcomp-preload-") as tmp:
            r = preload_path_errors(Path(tmp))
        e = r["mean_error_mm"]
        r["timing"] = {m: timing_verdict(r["cycles"][m], r["exceed_count"][m]) for m in ("aware", "blind")}
        runs.append(r)
        u = e["uncompensated"]
        print(f"{k + 1:<4} {u:14.4f} {e['aware']:9.4f} ({100 * e['aware'] / u:4.1f} %) "
              f"{e['blind']:9.4f} ({100 * e['blind'] / u:4.1f} %)   deadlines exceeded: "
              + ", ".join(f"{m} {100 * t['exceeded_share']:.1f} %" for m, t in r["timing"].items()))
    if args.json:
        Path(args.json).write_text(json.dumps(runs, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
