"""`make bench`: every benchmark of the project in one table (a script, not a test).

Rows: the model's batch speed and fit times (bench_model.py), diagnose (bench_diagnose.py), the
cycle's work p50/p99 on the Python and the compiled path for the springs alone, every library effect and
every effect with an identified preload, each against the C loop's work in the same run
(bench_effects.py), the 1 ms cycle's work and exceed rate while the service runs as `make run` starts
it, round trips of PLC-style reads of the to_plc block over Modbus and, when pyads and an ADS server are
there, ADS, the latency from a CAN frame to the PLC's register (bench_latency.py, PLC cycle 1 ms) and the
HIL circle's exceeded share, quiet and beside one busy process (bench_hil_deadlines.py; ``--no-hil``
leaves the two out).
Every figure is a median, a percentile, a rate or a ratio; nothing passes or fails on an absolute
time, because the machine decides those.

    .venv/bin/python benchmarks/bench_all.py [--service-s 5] [--reads 1000] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import logging
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "benchmarks"))

import bench_diagnose
import bench_effects
import bench_hil_deadlines
import bench_latency
import bench_model
import bench_trace

from hil.testing import free_port, wait_for_port, write_config
from plc_link.register_map import RegisterMap
from tools.pyads_connection import open_ads, read_cycle_count
from tools.status_cmd import BlockReader


def pct(samples_s: list[float]) -> str:
    us = np.asarray(samples_s) * 1e6
    return f"p50 {np.percentile(us, 50):.0f} µs, p99 {np.percentile(us, 99):.0f} µs"


def timed(fn, n: int) -> list[float]:
    out = []
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t0)
    return out


def modbus_rtt(port: int, reads: int) -> list[float]:
    reader = BlockReader(RegisterMap.from_yaml(ROOT / "config" / "registers.yaml"), "127.0.0.1", port)
    try:
        reader.read()                                   # connect outside the timing
        return timed(reader.read, reads)
    finally:
        reader.close()


def ads_rtt(reads: int) -> tuple[list[float] | None, str]:
    """Round trips of a pyads read by name, or (None, why not)."""
    conn, why = open_ads()
    if conn is None:
        return None, f"not available: {why}"
    import pyads

    try:
        read_cycle_count(conn)
        return timed(lambda: read_cycle_count(conn), reads), ""
    except pyads.ADSError as e:
        return None, f"not available: {e}"
    finally:
        conn.close()


def service_rows(seconds: float, reads: int) -> list[tuple[str, str, str]]:
    """Run the service as `make run` does (in its own process), read it, and read its task info."""
    with tempfile.TemporaryDirectory() as tmp:
        port = free_port()
        cfg = write_config(Path(tmp), {"plc": {"port": port}, "monitoring": {"port": free_port()},
                                       "cycle": {"stats_log_interval_s": 0}})
        stats = Path(tmp) / "stats.json"
        proc = subprocess.Popen([sys.executable, "-m", "tools.cli", "run", "--config", str(cfg), "--duration",
                                 str(seconds), "--stats-json", str(stats)], cwd=ROOT,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        try:
            wait_for_port(port, proc, 60.0)
            mb = modbus_rtt(port, reads)
            ads, why = ads_rtt(reads)
        finally:
            proc.wait(timeout=seconds + 60)
        s = json.loads(stats.read_text())
    ex = s["exec_us"]
    return [
        ("cycle work (1 ms task, `make run` set-up)", f"p50 {ex['p50']:.0f} µs, p99 {ex['p99']:.0f} µs",
         f"{s['cycles']} cycles in {seconds:g} s; p99 = {ex['p99'] / 1000:.2f} of the period"),
        ("cycles exceeded", f"{100 * s['exceed_count'] / max(s['cycles'], 1):.2f} %",
         f"period jitter p99.9 {s['period_jitter_us']['p999']:.0f} µs"),
        ("Modbus round trip (to_plc block, FC4)", pct(mb), f"{reads} reads, one client, while the cycle runs"),
        ("ADS round trip (read by name)  [issue 10]", pct(ads) if ads else "—",
         f"{reads} reads with pyads" if ads else why),
    ]


def model_rows() -> list[tuple[str, str, str]]:
    m = bench_model.main()
    d = bench_diagnose.main()
    e = bench_effects.main(["--blocks", "10"])
    tr = bench_trace.main(["--blocks", "20"])
    verdict = d["result"]
    c = e.get("C reference", {"p50_us": float("nan")})
    cycle = [(f"cycle work, {name}, {path}  [issue 25]",
              f"p50 {e[name][f'{key}_p50_us']:.1f} µs, p99 {e[name][f'{key}_p99_us']:.0f} µs",
              f"{e[name][f'{key}_x_c']:.1f} x the C loop's work (p50 {c['p50_us']:.1f} µs) in the same run")
             for name in ("springs only", "every effect", "every effect, preload identified")
             for path, key in (("Python path", "python"), ("compiled", "compiled"))]
    return cycle + [
        ("cycle work, every library effect  [issue 11]", f"ratio {e['every effect']['ratio']:.2f} to springs only",
         (f"{e['every effect']['python_us']:.0f} µs against {e['springs only']['python_us']:.0f} µs (Python path); "
          f"compiled {e['every effect']['compiled_ratio']:.2f}; a sample and new joints every cycle")),
        ("cycle work with the trace on  [issue 29]", f"ratio {tr['ratio']:.3f} to off",
         (f"p50 {tr['p50_us_on']:.1f} against {tr['p50_us_off']:.1f} µs, {tr['blocks']} alternating blocks; "
          f"{tr['written']} of {tr['traced']} cycles written")),
        ("model batch speed", f"{m['body_predictions_per_s']:,.0f} predictions/s",
         f"{m['batch_prediction_rows']:,} rows, one core, kinematics precomputed"),
        ("  … including kinematics", f"{m['body_predictions_per_s_including_kinematics']:,.0f} predictions/s",
         f"ratio {m['body_predictions_per_s_including_kinematics'] / m['body_predictions_per_s']:.2f}"),
        ("fit, 36 parameters, 5,355 rows", f"median {m['fit_reference_5355_rows_s']:.2f} s", ""),
        ("fit, 6,426 rows", f"median {m['fit_6426_rows_s']:.2f} s",
         f"ratio to 5,355 rows {m['fit_6426_rows_s'] / m['fit_reference_5355_rows_s']:.2f}"),
        ("diagnose, one hidden effect", f"median {d['diagnose_s_median']:.2f} s",
         f"{d['rows']} rows; found {verdict[1]} joint {verdict[2]}"),
        ("  … the command with its HTML report", f"median {d['command_with_report_s_median']:.2f} s", ""),
    ]


def loop_rows() -> list[tuple[str, str, str]]:
    """The latency from a CAN frame to the PLC's register, and the HIL circle's deadlines."""
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / "lat.json"
        bench_latency.main(["--seconds", "6", "--plc-period-ms", "1", "--json", str(out)])
        lat = json.loads(out.read_text())
        bench_hil_deadlines.main(["--json", str(out)])
        hil = json.loads(out.read_text())
    rows = [("CAN frame -> PLC register (PLC cycle 1 ms)  [issue 25]", f"p50 {lat['p50_ms']:.2f} ms, p99 {lat['p99_ms']:.2f} ms",
             f"max {lat['max_ms']:.2f} ms, {lat['samples']} samples; target p99 <= 2.0 ms")]
    for r in hil:
        rows.append((f"HIL circle, {'one busy process' if r['busy'] else 'quiet'}  [issue 25]",
                     f"{100 * r['share']:.2f} % of deadlines exceeded",
                     f"{r['exceeded']} of {r['cycles']}; target <= {'5' if r['busy'] else '1'} %"))
    return rows


def table(rows: list[tuple[str, str, str]]) -> str:
    head = ("benchmark", "figure", "note")
    w = [max(len(r[k]) for r in [head, *rows]) for k in range(3)]
    line = "| " + " | ".join(f"{{:<{x}}}" for x in w) + " |"
    return "\n".join([line.format(*head), "|" + "|".join("-" * (x + 2) for x in w) + "|",
                      *(line.format(*r) for r in rows)])


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--service-s", type=float, default=5.0, help="how long the service runs, s")
    ap.add_argument("--reads", type=int, default=1000, help="round trips per protocol")
    ap.add_argument("--json", default=None, metavar="FILE", help="also write the rows as JSON")
    ap.add_argument("--no-hil", action="store_true", help="leave out the latency and the HIL circle (3 minutes)")
    args = ap.parse_args(argv)
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
    rows = service_rows(args.service_s, args.reads) + model_rows() + ([] if args.no_hil else loop_rows())
    print(table(rows))
    if args.json:
        Path(args.json).write_text(json.dumps([dict(zip(("benchmark", "figure", "note"), r)) for r in rows],
                                              indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
