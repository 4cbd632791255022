"""The health verdicts: /health healthy only when running, rising, unfaulted and under the exceed bound;
/health/live when the count rises; /health/ready when healthy with a fresh sensor and the PLC seen."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from io_process.health import READY_CHECKS, HealthMonitor
from plc_link.contract import FAULT_BITS, Fault, Status


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


# -- liveness and readiness apart --------------------------------------------------------------------
READY_BITS = int(Status.SENSOR_OK | Status.PLC_SEEN)


def run_for(m: HealthMonitor, seconds: float, status_word: int = READY_BITS, **kw) -> float:
    t = 0.0
    for k in range(int(seconds * 10) + 1):
        t = 0.1 * k
        m.update(t, {"task_state": 1, "cycle_count": 1000 * t, "exceed_count": kw.get("exceed_per_s", 0) * t,
                     "fault_word": kw.get("fault_word", 0), "status_word": status_word})
    return t


def test_a_clean_task_with_sensor_and_plc_is_live_healthy_and_ready():
    m = HealthMonitor(0.05)
    v = m.verdicts(run_for(m, 2.0))
    assert v["live"]["live"] and v["health"]["healthy"] and v["ready"]["ready"]
    assert set(v["ready"]["checks"]) == set(READY_CHECKS) and all(v["ready"]["checks"].values())
    assert v["live"]["cycle_count"] == 2000


def test_readiness_wants_a_fresh_sensor_and_the_plc_heartbeat_health_does_not():
    for missing, word in (("sensor", Status.PLC_SEEN), ("plc", Status.SENSOR_OK)):
        m = HealthMonitor(0.05)
        v = m.verdicts(run_for(m, 2.0, status_word=int(word)))
        assert v["live"]["live"] and v["health"]["healthy"]
        assert not v["ready"]["ready"] and [n for n, ok in v["ready"]["checks"].items() if not ok] == [missing]
    m = HealthMonitor(0.05)
    assert "PLC heartbeat" in m.verdicts(run_for(m, 1.0, status_word=int(Status.SENSOR_OK)))["ready"]["reason"]


def test_slipping_deadlines_and_faults_leave_the_task_live():
    """What a busy host or a latched fault does is no reason to restart: live stays true."""
    m = HealthMonitor(0.05)
    v = m.verdicts(run_for(m, 12.0, exceed_per_s=300.0))         # 30 % exceeded, as seen on a busy host
    assert v["live"]["live"] and not v["health"]["healthy"] and not v["ready"]["ready"]
    assert "30.0 % of cycles exceeded" in v["ready"]["reason"]
    m = HealthMonitor(0.05)
    v = m.verdicts(run_for(m, 2.0, fault_word=int(Fault.SENSOR_TIMEOUT)))
    assert v["live"]["live"] and not v["health"]["healthy"] and v["ready"]["reason"] == v["health"]["reason"]


def test_a_stuck_or_unread_task_is_not_live():
    m = HealthMonitor(0.05)
    assert m.verdicts(0.0)["live"] == {**m.verdicts(0.0)["live"], "live": False,
                                       "reason": "no reading of the process image yet"}
    for k in range(21):                               # the count stops after 0.5 s
        t = 0.1 * k
        m.update(t, {"task_state": 1, "cycle_count": 1000 * min(t, 0.5), "status_word": READY_BITS})
    v = m.verdicts(2.0)
    assert not v["live"]["live"] and "has not risen for 1.5 s" in v["live"]["reason"]


samples = st.lists(st.tuples(st.sampled_from([0, 1, 2]), st.integers(0, 3), st.integers(0, 2),
                             st.sampled_from([0, 1, 0x40]), st.integers(0, 0x3F)), min_size=0, max_size=20)


@settings(max_examples=100, deadline=None)
@given(samples, st.floats(0.0, 1.0), st.floats(0.0, 3.0))
def test_ready_implies_healthy_implies_live(rows, bound, wait_s):
    """Whatever the task does: each verdict is the conjunction of its checks, each probe's checks contain
    the weaker one's, and HTTP can serve them as 200/503 (the verdict is a bool)."""
    m = HealthMonitor(bound)
    t = cycles = exceeded = 0.0
    for state, rise, exceed, fault, status in rows:
        t += 0.1
        cycles += 50 * rise
        exceeded += min(exceed, 50 * rise)
        m.update(t, {"task_state": state, "cycle_count": cycles, "exceed_count": exceeded,
                     "fault_word": fault, "status_word": status})
    v = m.verdicts(t + wait_s)
    live, healthy, ready = v["live"]["live"], v["health"]["healthy"], v["ready"]["ready"]
    assert all(type(x) is bool for x in (live, healthy, ready))
    assert (not ready or healthy) and (not healthy or live)
    assert ready == all(v["ready"]["checks"].values())
    assert all(isinstance(v[p]["reason"], str) and v[p]["reason"] for p in v)
