"""Health from the I/O process: healthy while the service runs clean; not, with the reason, once the
sensor replay ends (a fault) or the service stops."""

from __future__ import annotations

import json
import time
import urllib.error
import urllib.request

import pyads
import pytest

from hil.testing import constant_log, free_port, write_config
from service.app import Service
from service.config import load_config
from testlib.metrics import scrape
from tools.pyads_connection import open_ads, read_cycle_count

pytestmark = pytest.mark.realtime


def health(port: int, path: str = "/health") -> tuple[int, dict]:
    try:
        with urllib.request.urlopen(f"http://127.0.0.1:{port}{path}", timeout=1.0) as r:
            return r.status, json.loads(r.read())
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read())


def wait_for_status(port: int, status: int, timeout: float = 20.0) -> dict | None:
    """The first health answer with HTTP ``status`` within ``timeout`` s (a guard, not a timing check)."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        code, body = health(port)
        if code == status:
            return body
        time.sleep(0.05)
    return None


def test_health_follows_the_task_and_its_faults(tmp_path):
    port = free_port()
    log = constant_log(tmp_path / "short.blf", [100.0, 0.0, 200.0, 0.0, 0.0, 0.0], seconds=3.0)
    cfg = load_config(write_config(tmp_path, {
        "monitoring": {"port": port, "health_max_exceed_rate": 1.0},      # machine timing must not decide it
        "source": {"replay": {"file": str(log), "loop": False}},
        "faults": {"overrun_trip_count": 1000}}))
    s = Service(cfg)
    s.start()
    try:
        ok = wait_for_status(port, 200)
        assert ok is not None and ok["healthy"] is True and ok["faults"] == []
        code, ready = health(port, "/health/ready")             # healthy, but no PLC has shown up
        assert code == 503 and ready["ready"] is False and ready["checks"]["plc"] is False
        # the replay ends after 3 s: the sensor falls silent, sensor_timeout latches, health says so
        bad = wait_for_status(port, 503)
        assert bad is not None and bad["healthy"] is False
        assert "sensor_timeout" in bad["reason"] and "sensor_timeout" in bad["faults"]
        code, ready = health(port, "/health/ready")
        assert code == 503 and ready["checks"]["sensor"] is False and ready["checks"]["no_fault"] is False
        code, live = health(port, "/health/live")                # the task still cycles: no restart
        assert code == 200 and live["live"] is True
    finally:
        s.stop()


def test_metrics_parse_and_their_counters_rise(tmp_path):
    from pymodbus.client import ModbusTcpClient

    http, modbus = free_port(), free_port()
    cfg = load_config(write_config(tmp_path, {"monitoring": {"port": http, "metrics": True,
                                                              "health_max_exceed_rate": 1.0},
                                              "plc": {"port": modbus}, "faults": {"overrun_trip_count": 1000}}))
    s = Service(cfg)
    s.start()
    try:
        wait_for_status(http, 200, timeout=5.0)                    # the sampler has run (healthy or not)
        first = scrape(http)
        codec = s.rmap.codecs["to_plc"]
        with ModbusTcpClient("127.0.0.1", port=modbus, timeout=2) as c:
            assert c.connect()
            for _ in range(20):
                c.read_input_registers(codec.start, count=codec.words)
            c.write_registers(0x0000, [1])                          # refused: outside the map
        ads, why = open_ads(tcp_port=cfg.ads.port)
        assert ads is not None, why
        try:
            for _ in range(5):
                read_cycle_count(ads)                               # by name: handle, Read, release
            with pytest.raises(pyads.ADSError):
                ads.read_by_name("GVL_Comp.no_such_value", pyads.PLCTYPE_REAL)   # 0x710
        finally:
            ads.close()
        time.sleep(1.0)
        second = scrape(http)
    finally:
        s.stop()
    assert second[("stiffcomp_cycles_total", ())] > first[("stiffcomp_cycles_total", ())] > 0
    assert second[("stiffcomp_cycle_exec_microseconds_count", ())] > first[("stiffcomp_cycle_exec_microseconds_count", ())]
    fc4 = ("stiffcomp_requests_total", (("function", "FC4"), ("protocol", "modbus")))
    assert second[fc4] >= 20
    refused = [v for (n, labels), v in second.items() if n == "stiffcomp_requests_refused_total"
               and ("protocol", "modbus") in labels]
    assert sum(refused) >= 1
    assert second[("stiffcomp_sensor_sample_rate_hertz", ())] > 100          # the replay at 1 kHz
    # ADS requests by command, and the refused ones by their ADS error
    assert second[("stiffcomp_requests_total", (("function", "Read"), ("protocol", "ads")))] >= 5
    assert second[("stiffcomp_requests_total", (("function", "ReadWrite"), ("protocol", "ads")))] >= 6
    assert second[("stiffcomp_requests_refused_total", (("protocol", "ads"), ("reason", "ads_error_0x710")))] >= 1


def test_a_verdict_the_io_loop_stopped_refreshing_fails_every_probe():
    """The HTTP thread answers even when the I/O loop hangs: it must not serve the last good verdict."""
    from io_process.endpoints import PROBES
    from io_process.health import HealthMonitor
    from io_process.monitoring import STALE_S, Monitor
    from io_process.settings import MonitoringSettings

    mon = Monitor(None, MonitoringSettings())
    health = HealthMonitor(1.0)
    for k in range(11):
        health.update(10.0 + 0.1 * k, {"task_state": 1, "cycle_count": 100 * k, "status_word": 0x30})
    mon.verdicts = (11.0, health.verdicts(11.0))
    for probe, (_, key) in PROBES.items():
        assert mon.answer(probe, 11.0 + STALE_S / 2)[key] is True
        stale = mon.answer(probe, 11.0 + STALE_S + 0.5)
        assert stale[key] is False and "has not sampled the process image for 2.5 s" in stale["reason"]
