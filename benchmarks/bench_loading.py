"""Benchmark of bounded loading (issue 17): the YAML alias bomb and a CSV of garbage, each in a fresh
subprocess that reports its own time and peak RSS.

* bomb: the issue's model (9 levels of 9 aliases under ``noise.position_mm``) through `read_yaml`;
  side by side, a smaller bomb (6 levels, 531,441 leaves) through plain ``yaml.safe_load`` (what the
  loader did before) and through `read_yaml` (refused).
* garbage: a CSV with the right header and N lines of garbage through `read_measurements`.

Each figure is the median of RUNS runs. Run: .venv/bin/python benchmarks/bench_loading.py
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RUNS = 3
GARBAGE_LINES = 200_000

CHILD = """
import json, resource, sys, time
what, path = sys.argv[1], sys.argv[2]
t0 = time.perf_counter()
try:
    if what == "safe_load":
        import yaml
        yaml.safe_load(open(path).read())
    elif what == "read_yaml":
        from stiffness.yamlio import read_yaml
        read_yaml(path)
    else:
        from stiffness.measurements import read_measurements
        read_measurements(path)
    out = "loaded"
except Exception as e:
    out = type(e).__name__
print(json.dumps({"s": time.perf_counter() - t0, "rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "outcome": out}))
"""


def bomb(levels: int) -> str:
    names = "abcdefghij"
    lines = ['  - &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    lines += [f"  - &{names[k]} [{', '.join(['*' + names[k - 1]] * 9)}]" for k in range(1, levels)]
    return f"description:\n" + "\n".join(lines) + f"\nnoise:\n  position_mm: *{names[levels - 1]}\n"


def run(what: str, path: Path) -> dict:
    res = []
    for _ in range(RUNS):
        p = subprocess.run([sys.executable, "-c", CHILD, what, str(path)], cwd=ROOT, capture_output=True, text=True,
                           check=True, timeout=600)
        res.append(json.loads(p.stdout.strip().splitlines()[-1]))
    return {"s": statistics.median(r["s"] for r in res), "rss_mb": statistics.median(r["rss_mb"] for r in res),
            "outcome": res[0]["outcome"], "runs": RUNS}


def main() -> dict:
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        big, small = Path(tmp) / "bomb9.yaml", Path(tmp) / "bomb6.yaml"
        big.write_text(bomb(9))
        small.write_text(bomb(6))
        out["bomb9 read_yaml"] = run("read_yaml", big)
        out["bomb6 read_yaml"] = run("read_yaml", small)
        out["bomb6 yaml.safe_load (before)"] = run("safe_load", small)
        csv = Path(tmp) / "garbage.csv"
        header = (ROOT / "tests/data/reference_campaign.csv").read_text().splitlines()[0]
        row = ",".join(["garbage!"] * len(header.split(",")))
        csv.write_text(header + "\n" + "\n".join([row] * GARBAGE_LINES) + "\n")
        out[f"garbage CSV {GARBAGE_LINES} lines ({csv.stat().st_size / 1e6:.0f} MB)"] = run("measurements", csv)
    return out


if __name__ == "__main__":
    print(json.dumps(main(), indent=2))
