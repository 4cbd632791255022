"""A TwinCAT-side script for issue 10's "Done when", run in its own process: a real pyads client.

Against the running service it reads the task's cycle and exceed counts twice, the GVL_Comp
corrections (sum read by name), collects notifications of the corrections, and asks for an unknown
symbol before reading on the same connection. It prints one JSON document.
Usage: python -m testlib.ads_probe HOST:PORT
"""

from __future__ import annotations

import json
import sys
import threading
import time

import pyads

from testlib.pyads_callbacks import delete_notification

TASK = "TwinCAT_SystemInfoVarList._TaskInfo[1]."
CORR = [f"GVL_Comp.correction_q{i}" for i in range(1, 7)]


def main() -> int:
    out: dict = {}
    with pyads.Connection("127.0.0.1.1.1", 851, sys.argv[1]) as plc:
        counts = [TASK + "CycleCount", "GVL_Comp.exceed_count"]
        (c0, e0), t0 = plc.read_list_by_name(counts).values(), time.monotonic()
        time.sleep(1.0)
        c1, e1 = plc.read_list_by_name(counts).values()
        first = c1
        # deadlines the host held the cycle past are counted by the cycle after the first that runs again
        # (io_base.deadlines): read until two more cycles have run, so a stall under way at the read is counted
        give_up = time.monotonic() + 10.0
        while c1 < first + 2 and time.monotonic() < give_up:
            time.sleep(0.001)
            c1, e1 = plc.read_list_by_name(counts).values()
        t1 = time.monotonic()
        out["cycles"], out["exceed"], out["elapsed_s"] = [c0, c1], [e0, e1], t1 - t0
        out["cycle_time_100ns"] = plc.read_by_name(TASK + "CycleTime", pyads.PLCTYPE_UDINT)
        out["corrections"] = list(plc.read_list_by_name(CORR).values())
        got, lock = [], threading.Lock()

        def cb(notification, name):
            _h, stamp, value = plc.parse_notification(notification, pyads.PLCTYPE_REAL)
            with lock:
                got.append((stamp.timestamp(), value))

        h = plc.add_device_notification(CORR[0], pyads.NotificationAttrib(
            4, pyads.constants.ADSTRANS_SERVERCYCLE, 0, 10), cb)
        give_up = time.monotonic() + 20.0          # a guard against a hang, not a timing requirement
        while time.monotonic() < give_up:
            with lock:
                if len(got) >= 10:
                    break
            time.sleep(0.05)
        delete_notification(plc, h)
        out["notifications"] = got
        try:
            plc.read_by_name("GVL_Comp.NoSuchSymbol", pyads.PLCTYPE_REAL)
            out["unknown_symbol"] = 0
        except pyads.ADSError as e:
            out["unknown_symbol"] = e.err_code
        out["after_error"] = plc.read_by_name(TASK + "CycleCount", pyads.PLCTYPE_UDINT)
        out["wall_time"] = time.time()
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
