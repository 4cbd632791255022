"""A PLC stand-in for the "Done when" test, run in its own process: a real pymodbus client.

It reads the cycle count twice, enables the correction with a running heartbeat, reads the
corrections, and tries writes outside the PLC's registers. It prints one JSON document.
Usage: python -m testlib.plc_probe PORT
"""

from __future__ import annotations

import json
import struct
import sys
import time

from pymodbus.client import ModbusTcpClient

BASE = 0x8000


def u32(words):
    return words[0] | (words[1] << 16)


def f32(words):
    return struct.unpack("<f", struct.pack("<HH", words[0], words[1]))[0]


def f32_words(x):
    return list(struct.unpack("<HH", struct.pack("<f", x)))


def counted(c, at_least: int, give_up_s: float = 10.0):
    """The service's registers, read again until its cycle count reaches ``at_least`` (``give_up_s`` at most)."""
    r, give_up = c.read_input_registers(BASE, count=32), time.monotonic() + give_up_s
    while u32(r.registers[4:6]) < at_least and time.monotonic() < give_up:
        time.sleep(0.001)
        r = c.read_input_registers(BASE, count=32)
    return r


def main() -> int:
    port = int(sys.argv[1])
    q = [float(v) for v in sys.argv[2].split(",")]
    out = {}
    with ModbusTcpClient("127.0.0.1", port=port, timeout=2) as c:
        assert c.connect()
        # from the cycle's first count on: the service's start can return before its task runs (a fresh clone's
        # CI twice read 0 first and 487-490 cycles a second later, the task started half a second into the window)
        r0 = counted(c, 1)
        t0 = time.monotonic()
        time.sleep(1.0)
        # deadlines the host held the cycle past are counted by the cycle after the first that runs again
        # (io_base.deadlines): read until two more cycles have run, so a stall under way at the read is counted
        r1 = counted(c, u32(c.read_input_registers(BASE, count=32).registers[4:6]) + 2)
        t1 = time.monotonic()
        out["cycles"] = [u32(r0.registers[4:6]), u32(r1.registers[4:6])]
        out["exceed"] = [u32(r0.registers[6:8]), u32(r1.registers[6:8])]
        out["elapsed_s"] = t1 - t0
        # enable with a running heartbeat, at pose q
        words = [0x1, 0]
        for v in q:
            words += f32_words(v)
        c.write_registers(BASE, words)
        # 0.4 s of heartbeats, then on until the cycle has run on with the correction applied and unchanged
        # (a host that holds the cycle meanwhile delays its ramp-in; it must not fail the reading)
        k, prev, give_up = 0, None, time.monotonic() + 10.0
        while True:
            k += 1
            c.write_register(BASE + 1, k)
            time.sleep(0.01)
            if k < 40:
                continue
            r = c.read_input_registers(BASE, count=60).registers
            now = (u32(r[4:6]), r[0x10:0x1C])
            if (r[1] & 0x2 and prev is not None and now[0] > prev[0] and now[1] == prev[1]
                    or time.monotonic() > give_up):
                break
            prev = now
        out["status_word"] = r[1]
        out["fault_word"] = r[2]
        out["correction_deg"] = [f32(r[0x10 + 2 * i: 0x12 + 2 * i]) for i in range(6)]
        out["wrench"] = [f32(r[0x20 + 2 * i: 0x22 + 2 * i]) for i in range(6)]
        out["deflection"] = [f32(r[0x30 + 2 * i: 0x32 + 2 * i]) for i in range(6)]
        # writes outside the PLC's registers
        before = c.read_holding_registers(BASE, count=14).registers
        refused = {}
        for name, addr, vals in (("not_plc_register", BASE + 0x20, [1]), ("outside_map", 0x0000, [1]),
                                 ("spanning", BASE + 0x0C, [1, 2, 3, 4])):
            resp = c.write_registers(addr, vals)
            refused[name] = resp.exception_code if resp.isError() else 0
        out["refused"] = refused
        out["holding_unchanged"] = c.read_holding_registers(BASE, count=14).registers == before
        c.write_register(BASE, 0)      # disable
    print(json.dumps(out))
    return 0


if __name__ == "__main__":
    sys.exit(main())
