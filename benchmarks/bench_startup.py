"""What the compiled cycle adds to a service's start (a script, not a test): `make test` starts the
service well over a hundred times, so this is multiplied.

Each run is a whole `stiffcomp run --duration 0.2` process (config/default.yaml on free ports), timed
from its launch to its exit, with ``cycle.compiled`` true and false in alternation (numba's cache warm,
as after `make install`). The service's own log line says how long the compiled path took to load
("compiled signal path ready in ...") in its thread beside the I/O process's start.

    .venv/bin/python benchmarks/bench_startup.py [--runs 5]
"""

from __future__ import annotations

import argparse
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def one(compiled: bool) -> tuple[float, float | None]:
    from hil.testing import free_port, write_config

    with tempfile.TemporaryDirectory() as tmp:
        cfg = write_config(Path(tmp), {"plc": {"port": free_port()}, "cycle": {"compiled": compiled}})
        t0 = time.perf_counter()
        out = subprocess.run([sys.executable, "-m", "tools.cli", "run", "--config", str(cfg), "--duration", "0.2"],
                             cwd=ROOT, capture_output=True, text=True, check=True)
        wall = time.perf_counter() - t0
    m = re.search(r"compiled signal path ready in ([0-9.]+) s", out.stderr + out.stdout)
    return wall, float(m.group(1)) if m else None


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    args = ap.parse_args(argv)
    one(True)                                   # numba's cache warm for this model
    walls: dict[bool, list[float]] = {True: [], False: []}
    loads = []
    for _ in range(args.runs):
        for compiled in (False, True):
            wall, load = one(compiled)
            walls[compiled].append(wall)
            if load is not None:
                loads.append(load)
    py, cc = float(np.median(walls[False])), float(np.median(walls[True]))
    print(f"stiffcomp run --duration 0.2, median of {args.runs} alternated runs: Python path {py:.2f} s, compiled "
          f"{cc:.2f} s: +{cc - py:.2f} s per start ({100 * (cc / py - 1):.0f} %); the compiled path loaded in "
          f"{np.median(loads):.2f} s (median) in its thread beside the I/O process's start")
    return 0


if __name__ == "__main__":
    sys.exit(main())
