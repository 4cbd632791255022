"""The trace's cost in the cycle (`stiffcomp run --trace`, issue 29): a script, not a test.

Two services built from config/default.yaml (the replay source, the every-effect cycle's usual work), one
tracing to a CSV file with its writer process running beside it, the other not. Their `Service.work` runs
in alternating blocks of cycles in this process, each cycle timed; the figure is each one's median cycle
(p50) and the ratio on/off, with the count of blocks. Afterwards the trace holds every cycle it was given.

    .venv/bin/python benchmarks/bench_trace.py [--blocks 30] [--cycles 1000] [--json FILE]
"""

from __future__ import annotations

import argparse
import gc
import json
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from service.app import Service
from service.config import load_config
from service.trace import TraceOptions, TraceWriter
from stiffness.data.trace_file import read_trace


def block(service: Service, t0: float, cycles: int, out: list[float]) -> float:
    work, clock = service.work, time.perf_counter
    t = t0
    for _ in range(cycles):
        t += 0.001
        a = clock()
        work(t, False)
        out.append(clock() - a)
        service.info.record(0.0, None)
    return t


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=30)
    ap.add_argument("--cycles", type=int, default=1000)
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    cfg = load_config(ROOT / "config" / "default.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        options = TraceOptions(Path(tmp) / "trace.csv")
        off, on = Service(cfg), Service(cfg, options)
        writer = TraceWriter(on.trace, options)
        writer.start()
        times = {"off": [], "on": []}
        t = {"off": 0.0, "on": 0.0}
        try:
            for name, s in (("off", off), ("on", on)):
                t[name] = block(s, t[name], 200, [])             # warm up
            gc.disable()
            for _ in range(args.blocks):
                for name, s in (("off", off), ("on", on)):
                    t[name] = block(s, t[name], args.cycles, times[name])
        finally:
            gc.enable()
            counts = writer.stop()
            for s in (off, on):
                s.stop()
        written = len(read_trace(options.path))
    p50 = {k: float(np.median(v)) * 1e6 for k, v in times.items()}
    out = {"p50_us_off": p50["off"], "p50_us_on": p50["on"], "ratio": p50["on"] / p50["off"],
           "blocks": args.blocks, "cycles_per_block": args.cycles, "traced": counts["cycles"], "written": written,
           "lost": counts["lost"]}
    print(f"cycle work p50 (Service.work, {args.blocks} alternating blocks of {args.cycles} cycles): trace off "
          f"{p50['off']:.1f} µs, on {p50['on']:.1f} µs: ratio {out['ratio']:.3f}; the trace holds {written} of "
          f"{counts['cycles']} cycles ({counts['lost']} lost)")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
