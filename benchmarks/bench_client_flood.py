"""Issue 17, item 5: how long a new pyads client and a new Modbus client take to get an answer from the
running service (`stiffcomp run`, default limits: max_clients 64) with no other client, and with 100
idle TCP connections open to each of the ADS and Modbus ports. Both conditions in one run, alternated,
``--runs`` times each; prints medians, maxima and the ratio (a script, not a test).

    .venv/bin/python benchmarks/bench_client_flood.py [--runs 5] [--idle 100]
"""

from __future__ import annotations

import argparse
import socket
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pyads
from pymodbus.client import ModbusTcpClient

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from hil.run import ServiceProcess
from hil.testing import free_port, write_config

TASK = "TwinCAT_SystemInfoVarList._TaskInfo[1].CycleCount"


def answer_times(ads: int, mb: int) -> tuple[float, float]:
    """Seconds from connecting to the answer: a pyads read by name, a Modbus read of two registers."""
    t0 = time.perf_counter()
    plc = pyads.Connection("127.0.0.1.1.1", 851, f"127.0.0.1:{ads}")
    plc.open()
    try:
        plc.read_by_name(TASK)
    finally:
        plc.close()
    t1 = time.perf_counter()
    with ModbusTcpClient("127.0.0.1", port=mb, timeout=5, retries=0) as c:
        if not c.connect() or c.read_input_registers(0x8004, count=2).isError():
            raise RuntimeError("the Modbus read failed")
    return t1 - t0, time.perf_counter() - t1


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--idle", type=int, default=100)
    a = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        ads, mb = free_port(), free_port()
        service = ServiceProcess(write_config(Path(tmp), {"plc": {"port": mb}, "ads": {"port": ads}}), Path(tmp))
        times = {"quiet": [], "flooded": []}
        try:
            service.wait_running()
            for _ in range(a.runs):
                times["quiet"].append(answer_times(ads, mb))
                idle = [socket.create_connection(("127.0.0.1", p), timeout=10) for p in (ads, mb) for _ in range(a.idle)]
                try:
                    times["flooded"].append(answer_times(ads, mb))
                finally:
                    for s in idle:
                        s.close()
        finally:
            service.stop()
    q, f = np.array(times["quiet"]) * 1e3, np.array(times["flooded"]) * 1e3
    print(f"{a.runs} runs each, alternated; ms from connect to answer (median / max)")
    for k, name in enumerate(("pyads read", "Modbus read")):
        print(f"  {name:12s} no other client {np.median(q[:, k]):7.1f} / {q[:, k].max():7.1f}   "
              f"{a.idle} idle on each port {np.median(f[:, k]):7.1f} / {f[:, k].max():7.1f}   "
              f"ratio of medians {np.median(f[:, k]) / np.median(q[:, k]):.2f}")


if __name__ == "__main__":
    main()
