"""Issue 10's "Done when": the running service, and a pyads script in another process.

It reads `_TaskInfo[1].CycleCount` rising at about 1000/s, reads the GVL_Comp corrections equal to
the Modbus registers (a constant load: the correction is the same in every cycle once settled),
receives notifications of the corrections stamped with the cycle's time, and gets 0x710 for an
unknown symbol and then reads on the same connection.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time

import numpy as np
import pytest
from pymodbus.client import ModbusTcpClient

from hil.testing import constant_log, free_port, write_config
from service.app import Service
from service.config import load_config
from testlib.common import ROOT

pytestmark = pytest.mark.realtime

PROBE = ["-m", "testlib.ads_probe"]      # run from the repository's root, where testlib is


def until_the_correction_holds(port: int, codec, timeout_s: float = 20.0) -> None:
    """The correction ramps in at its rate limit and then holds: read it over Modbus until two reads, 20 ms
    and some cycles apart, agree and it is applied (later where the host holds the cycle meanwhile)."""
    names = [f"correction_q{i}" for i in range(1, 7)]
    prev, give_up = None, time.monotonic() + timeout_s
    with ModbusTcpClient("127.0.0.1", port=port, timeout=2) as c:
        assert c.connect()
        while time.monotonic() < give_up:
            v = dict(zip(codec.names, codec.decode(c.read_input_registers(codec.start, count=codec.words).registers)))
            now = (v["cycle_count"], [v[n] for n in names])
            if prev is not None and now[0] > prev[0] and now[1] == prev[1] and max(map(abs, now[1])) > 1e-3:
                return
            prev = now
            time.sleep(0.02)
    raise AssertionError(f"the correction did not settle within {timeout_s} s: {prev}")


def test_pyads_script_against_the_running_service(tmp_path):
    log = constant_log(tmp_path / "load.blf", [200.0, -100.0, 300.0, 10.0, 5.0, 2.0], seconds=1.0)
    ads_port, modbus_port = free_port(), free_port()
    cfg = load_config(write_config(tmp_path, {
        "plc": {"port": modbus_port, "enable_on_start": True},
        "ads": {"port": ads_port},
        "source": {"replay": {"file": str(log)}},
        "gravity": {"tool": {"mass_kg": 0.0}, "bias": [0.0] * 6},
        "faults": {"overrun_trip_count": 1000, "plc_heartbeat_timeout_ms": 0},
    }))
    s = Service(cfg)
    s.start()
    try:
        until_the_correction_holds(modbus_port, s.rmap.codecs["to_plc"])
        p = subprocess.run([sys.executable, *PROBE, f"127.0.0.1:{ads_port}"], capture_output=True, text=True,
                           timeout=120, check=False, cwd=ROOT)
        assert p.returncode == 0, p.stderr
        out = json.loads(p.stdout)
        codec = s.rmap.codecs["to_plc"]
        with ModbusTcpClient("127.0.0.1", port=modbus_port, timeout=2) as c:
            assert c.connect()
            words = c.read_input_registers(codec.start, count=codec.words).registers
        modbus = dict(zip(codec.names, codec.decode(words)))
    finally:
        s.stop()
    (c0, c1), (e0, e1), elapsed = out["cycles"], out["exceed"], out["elapsed_s"]
    # 1 ms deadlines: never faster than 1000/s; a loaded host may skip deadlines (counted in exceed_count,
    # which also counts the overrunning cycles, so the sum only bounds from above), not add cycles
    assert (c1 - c0) / elapsed < 1100, (c1 - c0) / elapsed
    assert (c1 - c0 + e1 - e0) / elapsed > 500, (c1 - c0, e1 - e0, elapsed)
    assert out["cycle_time_100ns"] == 10_000
    ads = np.array(out["corrections"], dtype=np.float32)
    assert np.abs(ads).max() > 1e-3                      # the correction is active
    np.testing.assert_array_equal(ads, np.array([modbus[f"correction_q{i}"] for i in range(1, 7)], np.float32))
    notes = out["notifications"]
    assert len(notes) >= 10
    assert all(np.float32(v) == ads[0] for _, v in notes)
    assert all(abs(stamp - out["wall_time"]) < 60.0 for stamp, _ in notes)     # FILETIME of the cycles
    assert out["unknown_symbol"] == 0x710
    assert out["after_error"] > c1
