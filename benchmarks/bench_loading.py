"""Benchmark of bounded loading (issue 17): the YAML alias bomb and a CSV of garbage, each loaded
in a fresh subprocess that reports its own time and peak RSS, with this tree and (side by side)
with the tree before the change (``git archive BASE stiffness``, BASE = 09476e1 by default).

* bomb: a model with N levels of 9 aliases under ``noise.position_mm`` (9**N leaves) through
  `StiffnessModel.from_yaml`. The issue's bomb is N = 9; before the change it is run at N = 6 and 7
  only (N = 9 took over 60 s and 2 GB), under a 4 GB address-space limit.
* garbage: a CSV with the right header and 200,000 lines of garbage through `read_measurements`.

Each figure is the median of RUNS runs. Run: .venv/bin/python benchmarks/bench_loading.py [BASE]
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

from stiffness.effects.joint_spring import JointSpring

ROOT = Path(__file__).resolve().parents[1]
RUNS = 3
GARBAGE_LINES = 200_000

CHILD = """
import json, resource, sys, time
resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))
what, path = sys.argv[1], sys.argv[2]
t0 = time.perf_counter()
try:
    if what == "model":
        from stiffness.model.stiffness_model import StiffnessModel
        StiffnessModel.from_yaml(path)
    else:
        from stiffness.data.measurements import read_measurements
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
    return (f"robot: {ROOT / 'config/robots/kr125.yaml'}\ndescription:\n" + "\n".join(lines)
            + f"\nnoise:\n  position_mm: *{names[levels - 1]}\neffects:\n  - {{effect: {JointSpring.name}, joint: 1}}\n")


def run(what: str, path: Path, tree: Path = ROOT) -> dict:
    res = []
    for _ in range(RUNS):
        p = subprocess.run([sys.executable, "-c", CHILD, what, str(path)], cwd=tree, capture_output=True, text=True,
                           check=True, timeout=600)
        res.append(json.loads(p.stdout.strip().splitlines()[-1]))
    return {"s": statistics.median(r["s"] for r in res), "rss_mb": statistics.median(r["rss_mb"] for r in res),
            "outcome": res[0]["outcome"], "runs": RUNS}


def main(base: str = "09476e1") -> dict:
    out = {}
    with tempfile.TemporaryDirectory() as tmp:
        before = Path(tmp) / "before"
        before.mkdir()
        archive = subprocess.run(["git", "archive", base, "stiffness"], cwd=ROOT, capture_output=True, check=True)
        subprocess.run(["tar", "-x", "-C", str(before)], input=archive.stdout, check=True)
        bombs = {n: Path(tmp) / f"bomb{n}.yaml" for n in (6, 7, 9)}
        for n, path in bombs.items():
            path.write_text(bomb(n))
            out[f"bomb {n} levels, now"] = run("model", path)
            if n < 9:
                out[f"bomb {n} levels, before"] = run("model", path, before)
        csv = Path(tmp) / "garbage.csv"
        header = (ROOT / "tests/data/reference_campaign.csv").read_text().splitlines()[0]
        row = ",".join(["garbage!"] * len(header.split(",")))
        csv.write_text(header + "\n" + "\n".join([row] * GARBAGE_LINES) + "\n")
        name = f"garbage CSV {GARBAGE_LINES} lines ({csv.stat().st_size / 1e6:.0f} MB)"
        out[f"{name}, now"] = run("measurements", csv)
        out[f"{name}, before"] = run("measurements", csv, before)
    return out


if __name__ == "__main__":
    print(json.dumps(main(*sys.argv[1:2]), indent=2))
