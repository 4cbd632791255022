"""The 1 ms cycle's work with Modbus/TCP Security on, side by side with it off (a script, not a test).

Alternating runs of the service as `make run` starts it (`stiffcomp run`, config/default.yaml on free
ports): TLS off, the PLC clients on plain Modbus TCP; TLS on (``plc.tls``, certificates made by
`io_base.certs`, plain Modbus beside it), the same clients over TLS with client certificates.
In every run 4 clients poll 32 input registers at 500 Hz each, as PLCs would; they start with the
service, poll from the moment it serves, and the service stops when they are done, so nearly the whole
run (all but its start-up) is under load. The figure is the cycle's work time p50 (``--stats-json``) of
each TLS-on run over the TLS-off run beside it, and the median of those ratios: TLS runs in the I/O
process, so it should not move the cycle's work (target: within 5 %).

    .venv/bin/python benchmarks/bench_tls.py [--pairs 3] [--duration 30] [--json FILE]
"""

from __future__ import annotations

import argparse
import json
import logging
import signal
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

CLIENTS, RATE_HZ, WORDS = 4, 500.0, 32


def poller(port: int, seconds: float, cert_dir: str | None) -> None:
    """One PLC-like client on absolute deadlines, plain or (with ``cert_dir``) over TLS as ``plc``."""
    from bench_cycle import poll
    from pymodbus.client import ModbusTcpClient, ModbusTlsClient

    from io_base.tls import client_context

    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)      # no line per refused try while it starts
    if cert_dir:
        d = Path(cert_dir)
        ctx = client_context(str(d / "ca.pem"), str(d / "plc.pem"), str(d / "plc.key"), check_hostname=False)
        c = ModbusTlsClient("127.0.0.1", port=port, sslctx=ctx, timeout=1.0, retries=0)
    else:
        c = ModbusTcpClient("127.0.0.1", port=port, timeout=1.0, retries=0)
    poll(c, seconds, RATE_HZ, WORDS, wait_s=60.0)        # started beside the service: wait for it


def run(folder: Path, seconds: float, tls: bool) -> dict:
    """One service run with the clients; its stats and the clients' counts."""
    from hil.testing import free_port, write_config

    plain, secure = free_port(), free_port()
    certs = folder / "certs"
    over = {"plc": {"port": plain}, "cycle": {"stats_log_interval_s": 0}}
    if tls:
        over["plc"]["tls"] = {"enabled": True, "port": secure, "cert": str(certs / "server.pem"),
                              "key": str(certs / "server.key"), "ca": str(certs / "ca.pem")}
    cfg = write_config(folder, over, name=f"service_{'tls' if tls else 'plain'}.yaml")
    stats = folder / "stats.json"
    stats.unlink(missing_ok=True)
    # the clients start with the service and poll as soon as it serves; it stops (SIGTERM) when they are done
    service = subprocess.Popen([sys.executable, "-m", "tools.cli", "run", "--config", str(cfg), "--stats-json",
                                str(stats), "--log-level", "WARNING"], cwd=ROOT)
    port = secure if tls else plain
    procs = [subprocess.Popen([sys.executable, __file__, "--poller", str(port), str(seconds),
                               str(certs) if tls else ""], stdout=subprocess.PIPE, text=True, cwd=ROOT)
             for _ in range(CLIENTS)]
    clients = [json.loads(p.communicate(timeout=seconds + 120)[0].strip().splitlines()[-1]) for p in procs]
    service.send_signal(signal.SIGTERM)
    service.wait(timeout=60)
    return {"tls": tls, "service": json.loads(stats.read_text()), "clients": clients}


def main() -> int:
    if len(sys.argv) > 1 and sys.argv[1] == "--poller":
        poller(int(sys.argv[2]), float(sys.argv[3]), sys.argv[4] if len(sys.argv) > 4 else None)
        return 0
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--pairs", type=int, default=3, help="TLS-off / TLS-on pairs of runs")
    ap.add_argument("--duration", type=float, default=30.0, help="s of load per run")
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args()
    from io_base import certs

    rows = []
    with tempfile.TemporaryDirectory(prefix="stiffcomp-bench-tls-") as tmp:
        folder = Path(tmp)
        (folder / "certs").mkdir()
        ca = certs.make_ca(folder / "certs")
        certs.make_server(ca, folder / "certs", ["localhost", "127.0.0.1"])
        certs.make_client(ca, folder / "certs", "plc", "operator")
        for k in range(args.pairs):
            order = (False, True) if k % 2 == 0 else (True, False)     # neither always runs first
            pair = {tls: run(folder, args.duration, tls) for tls in order}
            rows.append(pair)
    print(f"1 ms cycle, {CLIENTS} Modbus clients at {RATE_HZ:g} Hz reading {WORDS} registers, {args.duration:g} s "
          f"per run, {args.pairs} pairs of runs (TLS off, TLS on) alternating")
    print("| pair | exec p50 TLS off | exec p50 TLS on | ratio on/off | exec p99 off / on | requests off / on "
          "| client errors off / on |")
    print("|---|---|---|---|---|---|---|")
    ratios = []
    for k, pair in enumerate(rows, 1):
        off, on = pair[False], pair[True]
        ratio = on["service"]["exec_us"]["p50"] / off["service"]["exec_us"]["p50"]
        ratios.append(ratio)
        print(f"| {k} | {off['service']['exec_us']['p50']:.1f} us | {on['service']['exec_us']['p50']:.1f} us | "
              f"{ratio:.3f} | {off['service']['exec_us']['p99']:.0f} / {on['service']['exec_us']['p99']:.0f} us | "
              f"{sum(c['requests'] for c in off['clients'])} / {sum(c['requests'] for c in on['clients'])} | "
              f"{sum(c['errors'] for c in off['clients'])} / {sum(c['errors'] for c in on['clients'])} |")
    print(f"median ratio of the work p50, TLS on / off: {statistics.median(ratios):.3f} "
          f"(range {min(ratios):.3f} - {max(ratios):.3f}; target within 1.05)")
    if args.json:
        Path(args.json).write_text(json.dumps({"pairs": [{("on" if t else "off"): r for t, r in p.items()}
                                                         for p in rows], "ratios": ratios}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
