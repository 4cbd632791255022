"""The cost of building one cycle's `ToPlc` record: the contract's Producer (operator getters compiled
once) side by side with the one ``eval``-compiled lambda it replaced (a script, not a test).

Two figures, each from alternating blocks in one process (so the machine's drift falls on both alike),
as the ratio of the medians of the per-block mean times:

* the record alone, on the service's own task values and signals after one real cycle;
* one whole cycle of the service (`Service.work`: image, replay source, signal path, record, publish),
  with the service's producer swapped between blocks.

    .venv/bin/python benchmarks/bench_producer.py [--blocks 40] [--calls 20000] [--cycles 2000] [--json FILE]
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

from hil.testing import write_config
from plc_link.contract import TO_PLC, Producer, TaskState, ToPlc
from service.app import Service
from service.config import load_config


def eval_producer():
    """The mechanism before issue 18, as it was: every source joined into one lambda and eval'd."""
    body = ", ".join(v.source for v in TO_PLC)
    values = eval(f"lambda task, signals: ({body},)", {})
    make = ToPlc._make
    return lambda task, signals: make(values(task, signals))


def block(fn, task, signals, calls: int) -> float:
    t0 = time.perf_counter()
    for _ in range(calls):
        fn(task, signals)
    return (time.perf_counter() - t0) / calls


def cycles(service: Service, produce, n: int, t0: float) -> float:
    service.produce = produce
    start = time.perf_counter()
    for k in range(n):
        service.work(t0 + k * 1e-3, False)
    return (time.perf_counter() - start) / n


def alternate(blocks: int, run) -> dict[str, float]:
    """The median per-block time of each producer, the two taking turns (first one, then the other)."""
    times: dict[str, list[float]] = {"getters": [], "eval": []}
    gc.disable()
    try:
        for k in range(blocks):
            for name in ("getters", "eval")[:: 1 if k % 2 else -1]:
                times[name].append(run(name, k))
    finally:
        gc.enable()
    return {k: float(np.median(v)) for k, v in times.items()}


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--blocks", type=int, default=40)
    ap.add_argument("--calls", type=int, default=20000)
    ap.add_argument("--cycles", type=int, default=2000)
    ap.add_argument("--json")
    args = ap.parse_args()
    producers = {"getters": Producer(), "eval": eval_producer()}
    with tempfile.TemporaryDirectory() as tmp:
        service = Service(load_config(write_config(Path(tmp), {"source": {"replay": {"pacing": "fast"}}})))
        try:
            service.work(0.0, False)
            task, signals = service._task_values(TaskState.RUN), service.cycle.signals()
            producers["getters"].check(task, signals)
            assert producers["getters"](task, signals) == producers["eval"](task, signals)
            record = alternate(args.blocks, lambda name, k: block(producers[name], task, signals, args.calls))
            cycle = alternate(args.blocks, lambda name, k: cycles(service, producers[name], args.cycles,
                                                                  1.0 + 2 * k * args.cycles * 1e-3))
        finally:
            service.stop()
    out = {"blocks": args.blocks, "calls_per_block": args.calls, "cycles_per_block": args.cycles,
           "values": len(TO_PLC),
           "record_getters_us": round(record["getters"] * 1e6, 3), "record_eval_us": round(record["eval"] * 1e6, 3),
           "record_ratio": round(record["getters"] / record["eval"], 3),
           "cycle_getters_us": round(cycle["getters"] * 1e6, 2), "cycle_eval_us": round(cycle["eval"] * 1e6, 2),
           "cycle_ratio": round(cycle["getters"] / cycle["eval"], 3)}
    print(json.dumps(out, indent=2))
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
