"""The /health verdict: healthy only when running, rising, unfaulted and under the exceed bound."""

from __future__ import annotations

from plc_interface.contract import FAULT_BITS, Fault
from plc_interface.health import HealthMonitor


def feed(m: HealthMonitor, t0: float, seconds: float, exceed_per_s: float = 0.0, fault_word: int = 0,
         cycles0: float = 0.0, rate: float = 1000.0, task_state: int = 1) -> float:
    """Readings every 0.1 s of a task at ``rate`` cycles/s; returns the time of the last one."""
    t = t0
    for k in range(int(seconds * 10) + 1):
        t = t0 + 0.1 * k
        m.update(t, {"task_state": task_state, "cycle_count": cycles0 + rate * (t - t0),
                     "exceed_count": exceed_per_s * (t - t0), "fault_word": fault_word})
    return t


def test_a_running_task_without_fault_is_healthy():
    m = HealthMonitor(0.05, FAULT_BITS)
    t = feed(m, 0.0, 12.0, exceed_per_s=10.0)            # 1 % exceeded
    v = m.verdict(t)
    assert v["healthy"] is True and "1.0 %" in v["reason"]
    assert abs(v["cycles_per_s"] - 1000.0) < 1e-6


def test_each_cause_makes_it_unhealthy_with_its_reason():
    m = HealthMonitor(0.05, FAULT_BITS)
    assert m.verdict(0.0) == {**m.verdict(0.0), "healthy": False}           # nothing read yet
    t = feed(m, 0.0, 12.0, exceed_per_s=100.0)                              # 10 % exceeded
    assert not m.verdict(t)["healthy"] and "10.0 % of cycles exceeded" in m.verdict(t)["reason"]

    m = HealthMonitor(0.05, FAULT_BITS)
    t = feed(m, 0.0, 2.0, fault_word=1 << FAULT_BITS["sensor_timeout"])
    assert m.verdict(t)["reason"] == "fault word 0x0001: sensor_timeout"

    m = HealthMonitor(0.05, FAULT_BITS)
    t = feed(m, 0.0, 2.0, rate=0.0, cycles0=500)                            # the count is stuck
    assert not m.verdict(t)["healthy"] and "has not risen" in m.verdict(t)["reason"]

    m = HealthMonitor(0.05, FAULT_BITS)
    t = feed(m, 0.0, 2.0, task_state=2)
    assert "not running" in m.verdict(t)["reason"]


def test_old_exceeded_cycles_leave_the_window():
    m = HealthMonitor(0.05, FAULT_BITS, window_s=10.0)
    verdicts = []
    for k in range(141):                      # 14 s read every 0.1 s; 50 % exceeded in the first 2 s only
        t = 0.1 * k
        m.update(t, {"task_state": 1, "cycle_count": 1000 * t, "exceed_count": 500 * min(t, 2.0)})
        verdicts.append(m.verdict(t)["healthy"])
    assert verdicts[20] is False              # at 2 s: 50 % of the window
    assert verdicts[-1] is True               # at 14 s the bad start is older than the window


def test_health_names_the_payload_set_in_use_and_its_fault():
    m = HealthMonitor(max_exceed_rate=0.05)
    m.update(0.0, {"task_state": 1, "cycle_count": 0, "exceed_count": 0, "fault_word": int(Fault.PAYLOAD_INVALID),
                   "payload_active": 3})
    v = m.verdict(0.0)
    assert v["payload_active"] == 3 and v["faults"] == ["payload_invalid"] and not v["healthy"]
