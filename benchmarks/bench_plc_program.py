"""What one cycle of the PLC program costs the HIL's virtual PLC (a script, not a test): the generated library's
MAIN run by the structured-text runtime (`st_runtime`) through `hil.virtual_plc.VirtualPlc`, its requests served
by a process image in the same process (`hil.cell_network.ImageNetwork`, so no socket time is counted), against
the PLC's period. Also the cost of loading the program (parse and translate) once.

    .venv/bin/python benchmarks/bench_plc_program.py [--cycles 20000] [--period-ms 4] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from hil.cell_network import ImageNetwork
from hil.plc_program import generate_program
from hil.virtual_plc import VirtualPlc
from plc_link.contract import Status, to_plc
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap

ROOT = Path(__file__).resolve().parent.parent
RUNNING = int(Status.RUNNING | Status.ACTIVE | Status.SENSOR_OK | Status.PLC_SEEN)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cycles", type=int, default=20000)
    ap.add_argument("--period-ms", type=float, default=4.0)
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    rmap = RegisterMap.from_yaml(ROOT / "config" / "registers.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        program = generate_program(rmap, 502, 1, Path(tmp))
        image = ProcessImage(rmap)
        try:
            t = time.perf_counter()
            plc = VirtualPlc(program, ImageNetwork(image, rmap), rmap, lambda t: [10.0, -60.0, 90.0, 0.0, 60.0, 0.0],
                             True, args.period_ms / 1000.0)
            load_s = time.perf_counter() - t
            plc.new_log(args.cycles)
            cost = np.empty(args.cycles)
            for k in range(args.cycles):
                image.publish(to_plc(heartbeat=k & 0xFFFF, cycle_count=k, status_word=RUNNING,
                                     correction_q1=0.01, correction_q2=-0.02))
                t = time.perf_counter()
                plc.cycle(k * plc.period)
                cost[k] = time.perf_counter() - t
        finally:
            image.close()
    us = cost * 1e6
    row = {"cycles": args.cycles, "period_ms": args.period_ms, "load_s": round(load_s, 2),
           "cycle_us_median": round(float(np.median(us)), 1), "cycle_us_p99": round(float(np.percentile(us, 99)), 1),
           "cycle_us_max": round(float(us.max()), 1),
           "share_of_period_median": round(float(np.median(us)) / (args.period_ms * 1000.0), 4)}
    print(json.dumps(row))
    if args.json:
        Path(args.json).write_text(json.dumps(row, indent=2))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
