"""Issue 20's "Done when": ads-client (Node.js, v2, in its default PLC mode, not rawClient) against the
service as `make run` starts it (`stiffcomp run` with config/default.yaml, on free ports).

tests/plc_link/node/check.js connects with the fewest settings (the target's AMS address and the
service's TCP address; ads-client asks the service, as its AMS router, for its own address), reads
CycleCount by name twice 1 s apart, writes a PLC input by name and reads it back, subscribes by name
cyclic and on change, reads an unknown symbol (0x710, and the connection still works), lists the data
types, creates a handle, reconnects (port close, port connect) and connects a second client that names
its own AMS address. This test judges what it saw. `make test` installs ads-client from the committed
package-lock.json (`make node-deps`); without node and npm the test is skipped, and in CI (where they
are) it must run.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
from itertools import pairwise

import pytest

from hil.run import ServiceProcess
from hil.testing import ROOT, free_port, write_config
from plc_link.ads.datatypes import BASE_TYPES
from plc_link.ads.router import PORT_BASE
from plc_link.ads.session import Device
from plc_link.ads.symbols import SymbolTable
from plc_link.register_map import RegisterMap

NET_ID = "127.0.0.1.1.1"           # ads.net_id in config/default.yaml
NODE_DIR = ROOT / "tests" / "plc_link" / "node"
INSTALLED = shutil.which("node") is not None and (NODE_DIR / "node_modules" / "ads-client").is_dir()
pytestmark = [pytest.mark.realtime,
              pytest.mark.skipif(not INSTALLED and not os.environ.get("CI"),
                                 reason="node or ads-client not installed (make node-deps needs node and npm)")]


def test_ads_client_in_plc_mode_against_the_running_service(tmp_path, record_property):
    ads_port = free_port()
    cfg = write_config(tmp_path, {"plc": {"port": free_port()}, "ads": {"port": ads_port}})
    service = ServiceProcess(cfg, tmp_path)
    try:
        service.wait_running()
        p = subprocess.run(["node", str(NODE_DIR / "check.js"), "127.0.0.1", str(ads_port), NET_ID],
                           capture_output=True, text=True, timeout=180, check=False, cwd=NODE_DIR)
    finally:
        service.stop()
    record_property("transcript", p.stdout)
    assert p.returncode == 0, p.stdout + p.stderr
    assert service.proc.returncode == 0, service.result()[1]
    out = json.loads(p.stdout.rsplit("RESULT ", 1)[1])
    table = SymbolTable(RegisterMap.from_yaml(ROOT / "config" / "registers.yaml"))

    con = out["connect"]
    for lent in (con, out["reconnect"]):            # the router's answer to port connect: its Net ID, a free port
        assert lent["localAmsNetId"] == NET_ID and lent["localAdsPort"] >= PORT_BASE, lent
    assert out["second"] == {"localAmsNetId": "127.0.0.1.1.20", "localAdsPort": 32750}     # named by itself
    assert con["connected"] and con["tcSystemState"]["adsState"] == 5 and con["plcRuntimeState"]["adsState"] == 5
    assert con["symbolVersion"] == Device.FIRST_SYMBOL_VERSION
    assert out["state_notified"] == ["Run"]       # ads-client's own 0xF100 subscription, before any ReadState
    info = con["uploadInfo"]
    assert (info["symbolCount"], info["symbolLength"]) == (len(table.symbols), len(table.upload))
    assert (info["dataTypeCount"], info["dataTypeLength"]) == (len(table.types.types), len(table.types.upload))

    # 1 ms deadlines: never faster than 1000/s; a loaded host may skip deadlines, which the service counts
    # in ExceedCounter (it also counts overrunning cycles, so the sum only bounds from above)
    (c0, c1), (e0, e1), elapsed = out["cycles"], out["exceed"], out["elapsed_s"]
    assert elapsed >= 1.0
    assert (c1 - c0) / elapsed < 1100, (c1 - c0, elapsed)
    assert (c1 - c0 + e1 - e0) / elapsed > 500, (c1 - c0, e1 - e0, elapsed)

    written, read_back = out["q1"]
    assert read_back == written

    # cyclic notifications come every 10 ms whether or not the value changed (on change never repeats one):
    # in order, and rising over the five; two equal neighbours are a 1 ms task the host held for 10 ms
    cyclic = out["cyclic"]
    assert all(b >= a for a, b in pairwise(cyclic)) and cyclic[-1] > cyclic[0], cyclic
    seen = out["on_change"]["seen"]
    assert seen[0] == out["on_change"]["first"] and out["on_change"]["written"] in seen
    assert all(a != b for a, b in pairwise(seen)), seen        # on change: never the same value twice

    assert out["unknown"] == 0x710
    assert out["after_unknown"] > c1

    types = {t["name"]: (t["size"], t["ads"]) for t in out["types"]}
    assert types == {s.type_name: BASE_TYPES[s.type_name][::-1] for s in table.symbols}
    assert out["handle"] == {"size": 4, "type": "REAL", "value": written}
    assert out["states"] == {"system": "Run", "plc": "Run", "symbol_version": Device.FIRST_SYMBOL_VERSION}
    assert out["second_client"] > out["after_reconnect"] > out["after_unknown"]
