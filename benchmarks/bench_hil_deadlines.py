"""The HIL circle's exceeded share of the service's deadlines, on a quiet machine and with one busy
process beside it (a script, not a test).

Each run is `stiffcomp hil circle --json` (both passes, the service at its documented priority, the
virtual devices below it: hil/priority.py); the busy process is ``python3 -c 'while True: pass'`` at
normal priority, started before the run and ended after it. Runs alternate quiet / busy. The issue's
targets: <= 1 % quiet (the circle's verdict then says the cycle kept its deadlines), <= 5 % busy.

    .venv/bin/python benchmarks/bench_hil_deadlines.py [--runs 1] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def circle() -> dict:
    out = subprocess.run([sys.executable, "-m", "tools.cli", "hil", "circle", "--json"], cwd=ROOT, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out[out.index("{"):])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    rows = []
    for run in range(args.runs):
        for busy in (False, True):
            hog = subprocess.Popen([sys.executable, "-c", "while True: pass"]) if busy else None
            try:
                s = circle()
            finally:
                if hog is not None:
                    hog.kill()
                    hog.wait()
            share = s["exceed_count"] / max(s["cycles"], 1)
            rows.append({"run": run + 1, "busy": busy, "cycles": s["cycles"], "exceeded": s["exceed_count"],
                         "share": share, "verdict": s["timing"]["verdict"],
                         "mean_error_mm": s["mean_error_mm"], "mean_error_mm_uncompensated": s["mean_error_mm_uncompensated"]})
            r = rows[-1]
            print(f"run {r['run']}, {'one busy process' if busy else 'quiet':16}: {r['exceeded']} of {r['cycles']} "
                  f"cycles exceeded ({100 * share:.2f} %); path error {r['mean_error_mm']:.3f} mm "
                  f"(uncompensated {r['mean_error_mm_uncompensated']:.3f}); {r['verdict']}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps(rows, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
