"""The robot road's answers, timed at the robot (a script, not a test; docs/robot.md).

`stiffcomp run` serves a virtual KUKA RSI robot at 4 ms, or an ABB EGM one in path mode (a packet every 48 ms, as
shipped) or joint mode (every 4 ms) (`hil.virtual_robot`), beside its usual PLC
load: a Modbus TCP client reading the to_plc block every 4 ms (a PLC's cycle) and a pyads client reading a
symbol every 10 ms. The robot times each answer from its packet's send to the answer's arrival (the round
trip, which holds the reply latency and both kernels' UDP paths) and counts the answers that did not arrive
within its cycle; the service's own count (from a packet's arrival in the I/O loop to its answer's send) comes
from its --stats-json. ``--busy 1`` adds one busy process (``python3 -c 'while True: pass'``) for the whole run.
``--plc 0``: the cell without a PLC (``plc.role: none``, the robot's packets the service's only work).
``--cpu-latency held kernel`` times each row twice, the service holding the CPUs' idle wake-up at 0
(``cycle.cpu_latency_us: 0``; ``held`` is this script's default) and leaving it to the kernel (null, the
config's default), side by side.

Priorities as a cell would set them: the cycle at SCHED_FIFO 50 (config/default.yaml), the I/O process that
answers the robot at ``robot.realtime_priority`` (``--io-priority``, 40), and the virtual robot's own loop at
SCHED_FIFO 45 (``--robot-priority``; a robot controller is a real-time machine of its own: on this shared
host its loop must not wait behind the busy process, or its own lateness would pass for the service's).

    .venv/bin/python benchmarks/bench_robot_road.py [--seconds 60] [--busy 0 1] [--interface kuka_rsi abb_egm abb_egm_joint]
    .venv/bin/python benchmarks/bench_robot_road.py --circles      # the circle through each road in the HIL, RSI at
                                                                   # 12 and 4 ms, EGM at 48 and 24 ms
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))


def modbus_load(port: int, stop) -> None:
    """A PLC's reads: the to_plc block every 4 ms on absolute deadlines."""
    from pymodbus.client import ModbusTcpClient

    from hil.testing import CONFIG
    from io_base.deadlines import Deadlines
    from plc_link.register_map import RegisterMap

    codec = RegisterMap.from_yaml(CONFIG / "registers.yaml").codecs["to_plc"]
    c = ModbusTcpClient("127.0.0.1", port=port, timeout=1.0, retries=0)
    c.connect()
    d = Deadlines(0.004)
    while not stop.is_set():
        try:
            c.read_input_registers(codec.start, count=codec.words)
        except Exception:  # noqa: BLE001 - a load, never stopped by an error
            c.connect()
        d.advance(time.monotonic())
        d.sleep_until()
    c.close()


def steal_ticks() -> int:
    """The host's time taken from this VM's CPUs (the steal column of /proc/stat), in clock ticks."""
    return int(Path("/proc/stat").read_text().split("\n")[0].split()[8])


# the roads timed: their robot sections
ROADS = {"kuka_rsi": {"interface": "kuka_rsi"},
         "abb_egm": {"interface": "abb_egm", "abb_egm": {"mode": "path", "cycle_ms": 48}},
         "abb_egm_joint": {"interface": "abb_egm", "abb_egm": {"mode": "joint", "cycle_ms": 4}}}


def one(interface: str, seconds: float, busy: bool, io_priority: int, robot_priority: int,
        cpu_latency_us: int | None = 0, plc: bool = True) -> dict:
    from hil.robot_drive import drive
    from hil.run import ServiceProcess
    from hil.testing import free_port, write_config
    from hil.virtual_robot import VirtualRobot, controller_for
    from robot_road.settings import RobotSettings
    from stiffness.kinematics.robot import load_robot

    robot = load_robot(ROOT / "config" / "robots" / "kr125.yaml")
    with tempfile.TemporaryDirectory(prefix="bench-robot-") as tmp:
        folder = Path(tmp)
        section = {**ROADS[interface], "port": free_port(socket.SOCK_DGRAM), "realtime_priority": io_priority}
        modbus, ads = free_port(), free_port()
        plc_section = {"port": modbus, "enable_on_start": True, **({} if plc else {"role": "none"})}
        cfg = write_config(folder, {"plc": plc_section, "robot": section,
                                    "ads": {"port": ads}, "cycle": {"cpu_latency_us": cpu_latency_us}})
        service = ServiceProcess(cfg, folder)
        ctx = multiprocessing.get_context("spawn")
        stop = ctx.Event()
        load = ctx.Process(target=modbus_load, args=(modbus, stop))
        hog = None
        try:
            service.wait_running()
            if plc:
                load.start()
            if busy:            # the busy process, as bench_hil_deadlines.py makes it
                hog = subprocess.Popen([sys.executable, "-c", "while True: pass"])
            ads_proc = subprocess.Popen([sys.executable, "-c", ADS_LOAD.format(port=ads, seconds=seconds + 2)],
                                        cwd=ROOT) if plc else None
            settings = RobotSettings.model_validate(section)
            vr = VirtualRobot(controller_for(settings, robot), "127.0.0.1", settings.port,
                              lambda t: [0.0, -60.0, 90.0, 0.0, 60.0, 0.0])
            steal0 = steal_ticks()
            try:
                d = drive(vr, seconds, priority=robot_priority)
                steal_s = (steal_ticks() - steal0) / os.sysconf("SC_CLK_TCK")
            finally:
                vr.close()
        finally:
            stop.set()
            if load.pid is not None:
                load.join(10)
            if hog is not None:
                hog.kill()
                hog.wait()
            service.stop()
        if ads_proc is not None:
            ads_proc.wait(30)
        stats, _ = service.result()
    rtt = d.rtt_s[np.isfinite(d.rtt_s)] * 1000.0
    road = stats.get("robot", {})
    return {"interface": interface, "busy": busy, "seconds": seconds, "io_priority": io_priority,
            "robot_priority": robot_priority, "cpu_latency_us": cpu_latency_us, "plc": plc, "packets": len(d.answered),
            "late": d.late, "late_share": d.late / len(d.answered), "late_robot_on_time": d.late_on_time(),
            "robot_sent_late_1ms": int((d.send_lag_s > 0.001).sum()), "steal_s": steal_s,
            "rtt_ms": {"p50": float(np.percentile(rtt, 50)), "p99": float(np.percentile(rtt, 99)),
                       "max": float(rtt.max())},
            "service_answer_us": road.get("latency_us"), "service_exceed_count": stats.get("exceed_count"),
            "service_cycles": stats.get("cycles")}


ADS_LOAD = """
import time, pyads
with pyads.Connection("127.0.0.1.1.1", 851, "127.0.0.1:{port}") as plc:
    t_end = time.monotonic() + {seconds}
    while time.monotonic() < t_end:
        try:
            plc.read_by_name("TwinCAT_SystemInfoVarList._TaskInfo[1].CycleCount", pyads.PLCTYPE_UDINT)
        except pyads.ADSError:
            pass
        time.sleep(0.01)
"""


def circles() -> list[dict]:
    """`stiffcomp hil circle --json` through the PLC and through each robot road (RSI at 12 ms, #IPO as shipped, and
    at 4 ms, #IPO_FAST; EGM's path corrections every 48 ms, as shipped, and every 24 ms, the fastest ABB's manual
    allows): path errors and delay."""
    out = []
    with tempfile.TemporaryDirectory(prefix="bench-robot-") as tmp:
        fast = Path(tmp) / "egm24.yaml"
        fast.write_text("robot:\n  interface: abb_egm\n  abb_egm: {mode: path, cycle_ms: 24}\n")
        rsi4 = Path(tmp) / "rsi4.yaml"
        rsi4.write_text("robot:\n  interface: kuka_rsi\n  kuka_rsi: {cycle_ms: 4}\n")
        for road, extra in (("plc", []), ("kuka_rsi", []), ("kuka_rsi_4ms", ["--robot-config", str(rsi4)]),
                            ("abb_egm", []), ("abb_egm_24ms", ["--robot-config", str(fast)])):
            iface = None if road == "plc" else road.removesuffix("_24ms").removesuffix("_4ms")
            cmd = [sys.executable, "-m", "tools.cli", "hil", "circle", "--json",
                   *(["--robot-interface", iface] if iface else []), *extra]
            out.append(_circle(road, json.loads(subprocess.run(cmd, cwd=ROOT, check=True, capture_output=True,
                                                              text=True).stdout)))
            print(json.dumps(out[-1]), flush=True)
    return out


def _circle(road: str, s: dict) -> dict:
    return {"road": road, "mean_error_mm": s["mean_error_mm"], "mean_error_mm_uncompensated": s["mean_error_mm_uncompensated"],
            "reduction_pct": round(100 * (1 - s["mean_error_mm"] / s["mean_error_mm_uncompensated"]), 1),
            "delay_ms": s["delay_ms"], "late_answers": s["late_answers"], "reply_latency_p99_ms": s["reply_latency_p99_ms"],
            "part_error_mm": s["part_error_mm"], "exceeded_share": s["timing"]["exceeded_share"]}


def report(r: dict, busy: int, latency: str) -> None:
    s = r["service_answer_us"] or {}
    print(f"{r['interface']:13s} {'busy ' if busy else 'quiet'} {'PLC' if r['plc'] else 'none'} {latency:6s}: round trip at the robot p50 "
          f"{r['rtt_ms']['p50']:.3f} p99 {r['rtt_ms']['p99']:.3f} max {r['rtt_ms']['max']:.2f} ms; late {r['late']} of "
          f"{r['packets']} ({100 * r['late_share']:.3f} %), {r['late_robot_on_time']} to packets the robot sent on time "
          f"(it sent {r['robot_sent_late_1ms']} over 1 ms late; {r['steal_s']:.2f} s stolen by the VM's host); in the "
          f"service p50/p99/max {s.get('p50')}/{s.get('p99')}/{s.get('max')} us", flush=True)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--busy", type=int, nargs="+", default=[0, 1], choices=(0, 1))
    ap.add_argument("--interface", nargs="+", default=list(ROADS), choices=tuple(ROADS))
    from hil.priority import ROAD_IO_FIFO, ROBOT_FIFO

    ap.add_argument("--io-priority", type=int, default=ROAD_IO_FIFO, help="robot.realtime_priority of the service")
    ap.add_argument("--robot-priority", type=int, default=ROBOT_FIFO, help="SCHED_FIFO of the virtual robot's loop")
    ap.add_argument("--circles", action="store_true", help="the HIL circle through each road instead")
    ap.add_argument("--cpu-latency", nargs="+", default=["held"], choices=("held", "kernel"),
                    help="cycle.cpu_latency_us 0 (held, the default) and/or null (the kernel's), each row")
    ap.add_argument("--plc", type=int, nargs="+", default=[1], choices=(0, 1),
                    help="1: beside a PLC's Modbus and ADS clients (the default); 0: plc.role none, no client")
    ap.add_argument("--json", default=None, metavar="FILE")
    args = ap.parse_args(argv)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))      # a stopped run still stops its services
    if args.circles:
        res = circles()
    else:
        res = []
        for busy in args.busy:
            for interface in args.interface:
                for plc in args.plc:
                    for latency in args.cpu_latency:
                        r = one(interface, args.seconds, bool(busy), args.io_priority, args.robot_priority,
                                0 if latency == "held" else None, bool(plc))
                        res.append(r)
                        report(r, busy, latency)
    if args.json:
        Path(args.json).write_text(json.dumps(res, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
