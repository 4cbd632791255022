"""Where the service's cycle spends its time: `Service.work` as `make run` builds it (config/default.yaml, the
replay source, the compiled path), stepped in this process, each stage timed (a script, not a test).

The stages are the methods `Service.work` calls, each wrapped by a timer while the whole cycle is timed
without the wrappers in alternate cycles (the wrappers cost some 0.1 us each): the image's inputs, the source's
poll, the steady cycle's one call (`service.steady`), or the cycle of the glue (supervision and the signal
path), the record and the publish to the image; the trace (with ``--trace``). Every stage a version of the
service has is timed; the figure is each one's median (p50) and the whole cycle's p50 and p99, collector
frozen and off as in the task.

    .venv/bin/python benchmarks/bench_stages.py [--cycles 30000] [--trace] [--cold MB] [--json FILE]
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

# (label, owner attribute path, method): whichever the service's version has
STAGES = (("steady.run", "_steady", "run"),
          ("image.inputs", "image", "inputs"), ("source.poll", "source", "poll"),
          ("cycle.step", "cycle", "step"), ("cycle.advance", "cycle", "advance"),
          ("cycle.signals", "cycle", "signals"), ("record", "", "produce"),
          ("image.publish", "image", "publish"), ("image.publish_with", "image", "publish_with"),
          ("trace.put_cycle", "trace", "put_cycle"), ("trace.put_with", "trace", "put_with"))


def timed(fn, out: list[float]):
    clock = time.perf_counter

    def wrapper(*a, **kw):
        t0 = clock()
        r = fn(*a, **kw)
        out.append(clock() - t0)
        return r

    return wrapper


def main(argv: list[str] | None = None) -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=30_000)
    ap.add_argument("--trace", action="store_true", help="trace every cycle, as stiffcomp run --trace does")
    ap.add_argument("--cold", type=float, default=0.0, metavar="MB",
                    help="write over this much memory between cycles (what other processes do to the caches "
                         "during the cycle's sleep in a running service; 0: warm caches)")
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    from service.app import Service
    from service.config import load_config
    from service.trace import TraceOptions, TraceWriter

    cfg = load_config(ROOT / "config" / "default.yaml")
    cfg.plc.role, cfg.ads.enabled, cfg.monitoring.enabled = "none", False, False
    with tempfile.TemporaryDirectory() as tmp:
        options = TraceOptions(Path(tmp) / "trace.csv") if args.trace else None
        s = Service(cfg, options)
        s.wait_compiled()
        writer = TraceWriter(s.trace, options) if args.trace else None
        if writer is not None:
            writer.start()
        times: dict[str, list[float]] = {}
        wrapped, plain = [], []
        for label, owner, name in STAGES:
            obj = getattr(s, owner) if owner else s
            if obj is None or not hasattr(obj, name):
                continue
            times[label] = []
            wrapped.append((obj, name, timed(getattr(obj, name), times[label])))
            plain.append((obj, name, getattr(obj, name), name in vars(obj)))
        whole: list[float] = []
        t, clock, work = 0.0, time.perf_counter, s.work
        flush = np.zeros(int(args.cold * 1e6) // 8)
        try:
            for _ in range(2000):               # warm up
                t += 1e-3
                work(t, False)
            gc.collect()
            gc.freeze()
            gc.disable()
            for k in range(args.cycles):
                for obj, name, fn, *_ in (wrapped if k % 2 else plain):
                    setattr(obj, name, fn)
                if len(flush):
                    flush += 1.0
                t += 1e-3
                a = clock()
                work(t, False)
                b = clock()
                if not k % 2:
                    whole.append(b - a)
                s.info.record(b - a, None)
        finally:
            gc.enable()
            gc.unfreeze()
            for obj, name, fn, own in plain:      # as it was: an attribute of its own, or the class's method
                if own:
                    setattr(obj, name, fn)
                elif name in vars(obj):
                    delattr(obj, name)
            if writer is not None:
                writer.stop()
            s.stop()
    out = {label: float(np.median(v)) * 1e6 for label, v in times.items() if v}
    out["work p50"] = float(np.median(whole)) * 1e6
    out["work p99"] = float(np.percentile(whole, 99)) * 1e6
    out["cycles"] = args.cycles
    print(f"Service.work, {args.cycles} cycles ({'with' if args.trace else 'without'} trace"
          f"{f', {args.cold:g} MB written between cycles' if args.cold else ''}), median per stage:")
    for label, v in out.items():
        if label != "cycles":
            print(f"  {label:20s} {v:7.2f} us")
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
