"""Start-up cost of the commands an orchestrator or a person runs often: `stiffcomp health` (the probe)
and `stiffcomp --help`, beside a bare interpreter start (a script, not a test).

Standard library only, so the very same file measures any tree or image: on the host
(``.venv/bin/python benchmarks/bench_probe.py``) and inside the container
(``docker run --rm -v "$PWD/benchmarks:/b:ro" --entrypoint python3 stiffcomp /b/bench_probe.py``).
The probe asks a stand-in for the I/O process's HTTP endpoint, served here on a free port, that
answers every ``/health…`` path healthy; so what is measured is the command's own start-up, config
reading and one HTTP round trip. The commands run round-robin, ``--runs`` times each, so the machine's
drift falls on all alike; each is reported as the median wall time with its minimum and maximum, and
as a ratio to the bare interpreter's median of the same run.

    python benchmarks/bench_probe.py [--runs 5] [--warmup 1] [--cmd [LABEL=]COMMAND ...]
                                     [--probe-args=--live] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

ANSWER = json.dumps({"healthy": True, "live": True, "ready": True, "reason": "bench stand-in"}).encode()


class _Health(BaseHTTPRequestHandler):
    def do_GET(self) -> None:
        ok = self.path.startswith("/health")
        self.send_response(200 if ok else 404)
        self.send_header("Content-Type", "application/json")
        self.send_header("Content-Length", str(len(ANSWER) if ok else 0))
        self.end_headers()
        if ok:
            self.wfile.write(ANSWER)

    def log_message(self, *args) -> None:
        pass


def wall(argv: list[str]) -> float:
    """Wall time of one run, s; the command must exit 0 (a failing probe measures nothing)."""
    t0 = time.perf_counter()
    r = subprocess.run(argv, capture_output=True, text=True, check=False)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"{shlex.join(argv)}: exit code {r.returncode}\n{r.stdout}{r.stderr}")
    return dt


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5, help="runs of each command (default 5)")
    ap.add_argument("--warmup", type=int, default=1, help="uncounted runs first, which write the bytecode "
                    "cache where the interpreter may (default 1)")
    ap.add_argument("--cmd", action="append", default=None, metavar="[LABEL=]COMMAND",
                    help="how to start stiffcomp (default: stiffcomp on PATH); repeat it to measure several "
                    "trees side by side, e.g. --cmd before='env PYTHONPATH=/tmp/old python -m tools.cli'")
    ap.add_argument("--probe-args", default="", help="extra arguments of the probe, e.g. --probe-args=--live")
    ap.add_argument("--json", type=Path, default=None, help="also write the figures to this file")
    args = ap.parse_args(argv)

    server = ThreadingHTTPServer(("127.0.0.1", 0), _Health)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    port = server.server_address[1]
    cmds = dict(c.split("=", 1) if "=" in c.split(" ", 1)[0] else ("stiffcomp", c)
                for c in args.cmd or ["stiffcomp"])
    with tempfile.TemporaryDirectory(prefix="bench-probe-") as tmp:
        config = Path(tmp) / "service.yaml"
        config.write_text(f"monitoring: {{host: 127.0.0.1, port: {port}}}\n")
        commands = {"python -c pass": [sys.executable, "-c", "pass"]}
        for label, cmd in cmds.items():
            commands[f"{label} --help"] = [*shlex.split(cmd), "--help"]
            commands[f"{label} health"] = [*shlex.split(cmd), "health", *shlex.split(args.probe_args),
                                           "--config", str(config)]
        times: dict[str, list[float]] = {name: [] for name in commands}
        for i in range(args.warmup + args.runs):
            for name, argv_ in commands.items():
                dt = wall(argv_)
                if i >= args.warmup:
                    times[name].append(dt)
    server.shutdown()

    base = statistics.median(times["python -c pass"])
    print(f"{args.runs} runs each after {args.warmup} warm-up, round-robin; PYTHONDONTWRITEBYTECODE="
          f"{os.environ.get('PYTHONDONTWRITEBYTECODE', '')!r}; load average {os.getloadavg()[0]:.1f}")
    for label, cmd in cmds.items():
        print(f"  {label} = {cmd}")
    width = max(map(len, times))
    print(f"{'command':<{width}} {'median s':>9} {'min s':>7} {'max s':>7} {'x bare python':>14}")
    figures = {}
    for name, ts in times.items():
        med = statistics.median(ts)
        figures[name] = {"median_s": med, "min_s": min(ts), "max_s": max(ts), "runs": len(ts)}
        print(f"{name:<{width}} {med:9.3f} {min(ts):7.3f} {max(ts):7.3f} {med / base:14.1f}")
    if args.json is not None:
        args.json.write_text(json.dumps(figures, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
