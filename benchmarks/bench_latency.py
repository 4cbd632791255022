"""Latency from a CAN frame to the register a PLC reads (a script, not a test; docs/hil.md).

The virtual sensor, the service (`stiffcomp run`) and the virtual PLC run as separate processes, as in
`stiffcomp hil circle`; the sensor numbers its samples through the force and the PLC notes when each
number first shows up in the wrench registers (hil/latency.py). Prints p50/p99/max in ms.

    .venv/bin/python benchmarks/bench_latency.py [--seconds 5] [--plc-period-ms 1] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def main(argv: list[str] | None = None) -> int:
    from hil.latency import measure
    from hil.scenario import DEFAULT_SCENARIO, load_scenario
    from stiffness.model.stiffness_model import StiffnessModel

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default=str(DEFAULT_SCENARIO))
    ap.add_argument("--seconds", type=float, default=5.0)
    ap.add_argument("--plc-period-ms", type=float, default=None, help="the PLC's cycle, 1-4 ms (default: scenario)")
    ap.add_argument("--request-lead-us", type=float, default=None,
                    help="source.can.request_lead_us of the service (default: config/hil/service.yaml's, "
                         "400; 0: the request in the cycle, its answer read in the next)")
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    sc = load_scenario(args.scenario)
    if args.plc_period_ms is not None:
        sc.plc.period_ms = args.plc_period_ms
    model = sc.resolve(sc.model)
    robot = StiffnessModel.from_yaml(sc.resolve(sc.truth)).robot.source
    res = measure(sc, model, robot, args.seconds, args.request_lead_us)
    print(f"CAN frame -> PLC register: p50 {res['p50_ms']:.2f} ms, p99 {res['p99_ms']:.2f} ms, "
          f"max {res['max_ms']:.2f} ms over {res['samples']} samples (PLC cycle {res['plc_period_ms']:g} ms, "
          f"service cycle {res['service_cycle_ms']:g} ms, {res['service_exceed_count']} of "
          f"{res['service_cycles']} service cycles exceeded)")
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
