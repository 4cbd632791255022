"""Benchmark of `diagnose` (issue 3): a 6,426-row campaign with a hidden backlash, on this machine.

6 configurations x 3 axes x 17 load states x 3 readings x 7 bodies = 6,426 rows. Times the
diagnosis alone, and the whole command with its HTML report, each the median of 3 runs.
Run: .venv/bin/python benchmarks/bench_diagnose.py
"""

from __future__ import annotations

import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))

from discovery.campaigns import campaign, start_model

from hil.testing import truth_with
from stiffness.diagnose.discovery import diagnose
from stiffness.effects.backlash import Backlash


def main() -> dict:
    truth = truth_with([Backlash(3, np.radians(0.02), 5.0).to_config()])
    data = campaign(truth, seed=42, configs=6, repeats=3)
    model = start_model()
    times, verdict = [], None
    for _ in range(3):
        t0 = time.perf_counter()
        d = diagnose(model, data)
        times.append(time.perf_counter() - t0)
        verdict = (d.verdict, d.best.name if d.best else None, d.best.joint if d.best else None)
    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "campaign.csv"
        data.to_csv(csv)
        cmd = [sys.executable, "-m", "tools.cli", "diagnose", str(ROOT / "config/models/kr125_6dof.yaml"),
               str(csv), "--report", str(Path(tmp) / "report"), "--json"]
        wall = []
        for _ in range(3):
            t0 = time.perf_counter()
            subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True)
            wall.append(time.perf_counter() - t0)
    return {"rows": len(data), "diagnose_s_median": statistics.median(times),
            "command_with_report_s_median": statistics.median(wall), "result": verdict}


if __name__ == "__main__":
    print(json.dumps(main(), indent=2))
