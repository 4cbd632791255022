"""Fault injection in the closed loop: each fault ends in the documented safe state (docs/hil.md), and
nothing is written outside the register map. Every test checks both.

Safe state of the service (docs/register_map.md): the fault bit latched, status faulted and not
active, the correction ramped to zero (limits.fault_ramp_s) and held there. Safe state of the PLC
(the generated library the virtual PLC runs, docs/plc.md): with no fresh service heartbeat it applies no
correction, so the robot follows its references; once the service answers again MAIN resets the faults
the loss caused (bResetOnRecovery) and the compensation resumes.

The tests wait on events, not on windows of program time: "before the fault" is what the PLC read
before the fault was injected (a PLC cycle due before it may run after it on a loaded host), and the
service restart runs on a slower, longer circle so that a new service that takes long to start on a
loaded host still finds the cut going on.
"""

from __future__ import annotations

import numpy as np
import pytest

from hil.cell_network import PlcFaults
from plc_link.contract import Fault, Status
from testlib.hil import (
    EXAMPLES,
    Faults,
    compensated,
    corrections,
    mean_error,
    nothing_outside_the_map,
    scenario,
    value,
)

TRUTH = EXAMPLES / "truth_reference.yaml"
T_FAULT = 1.5                       # s after the cut started
FEED = 30.0                         # mm/s: a 7.3 s circle leaves room for the fault and the recovery
RESTART_FEED = 10.0                 # mm/s: 22 s, room for a new service's start-up on a loaded host


def at(r, t_from, t_to=np.inf):
    t = r.log.t
    return (t >= t_from) & (t < t_to)


def read_before(r, t_fault: float) -> np.ndarray:
    """The PLC cycles whose read completed before the fault was injected at ``t_fault`` (s after the start)."""
    return r.log.t_read - r.log.t0 < t_fault


def assert_working_before_the_fault(r):
    m = at(r, 0.3, T_FAULT) & read_before(r, T_FAULT) & r.log.link
    assert m.sum() > 50
    assert (value(r, "fault_word")[m] == 0).all()
    assert ((value(r, "status_word")[m].astype(int) & Status.ACTIVE) != 0).all()


def assert_service_safe(r, fault: str):
    """From the cycle the fault is first seen: latched, faulted, not active; the correction ramps to zero
    without growing and stays there; the robot ends on its references. No deadline: a loaded host may
    delay the trip, never the order of the states."""
    t, link = r.log.t, r.log.link
    bit = int(Fault.from_kind(fault))
    fw = np.nan_to_num(value(r, "fault_word")).astype(int)
    tripped = np.flatnonzero((t >= T_FAULT) & link & (fw & bit != 0))
    assert len(tripped), "the fault never tripped"
    m = (t >= t[tripped[0]]) & link
    assert m.sum() > 50
    fw, st = fw[m], value(r, "status_word")[m].astype(int)
    assert (fw & bit != 0).all(), np.unique(fw)
    assert (st & Status.FAULTED != 0).all() and (st & Status.ACTIVE == 0).all(), np.unique(st)
    c = np.abs(corrections(r)[m])
    assert np.all(np.diff(c, axis=0) <= 1e-7), "the correction grew after the fault"
    zero = np.flatnonzero((c == 0.0).all(axis=1))
    assert len(zero), "the correction never reached zero"
    assert (c[zero[0]:] == 0.0).all()
    assert len(c) - zero[0] > 20                             # held at zero, not just touched
    assert np.abs(r.log.q_cmd[m][-20:] - r.log.q_ref[m][-20:]).max() < 1e-9


def run(tmp_path, faults, feed: float = FEED):
    r, ev = compensated(scenario(feed), TRUTH, TRUTH, tmp_path, faults)
    assert nothing_outside_the_map(r) == []
    return r, ev


@pytest.mark.parametrize("kind, fault", [("stop", "sensor_timeout"), ("babble", "can_frame")])
def test_sensor_stops_or_babbles_garbage(tmp_path, kind, fault):
    r, _ = run(tmp_path, Faults(sensor=(kind, T_FAULT)))
    assert_working_before_the_fault(r)
    assert_service_safe(r, fault)


def test_plc_heartbeat_stops(tmp_path):
    r, _ = run(tmp_path, Faults(plc=PlcFaults(heartbeat_stop_at=T_FAULT)))
    assert_working_before_the_fault(r)
    assert_service_safe(r, "plc_heartbeat")


def assert_recovers(r, ev, lost_from: float, lost_to: float):
    """No correction while the link is lost; active again after, with the path error back down."""
    lost = at(r, lost_from, lost_to)
    assert lost.sum() > 20
    assert np.abs(r.log.applied[lost]).max() == 0.0
    assert np.abs(r.log.q_cmd[lost] - r.log.q_ref[lost]).max() < 1e-9
    st = np.nan_to_num(value(r, "status_word")).astype(int)
    back = np.flatnonzero(at(r, lost_to) & r.log.link & (st & Status.ACTIVE != 0) & (value(r, "fault_word") == 0))
    assert len(back), "the compensation never resumed"
    t_back = r.log.t[back[0]]
    resumed = at(r, t_back + 0.5, ev.t[ev.cut].max())
    assert resumed.sum() > 100, f"resumed only at t = {t_back:.2f} s"
    assert r.log.link[resumed].all()
    assert (value(r, "fault_word")[resumed] == 0).all()
    assert mean_error(ev, t_back + 0.5) < 0.3 * mean_error(ev, lost_from, lost_to)


def test_modbus_client_drops_and_reconnects(tmp_path):
    drop = 1.0                       # longer than the service's heartbeat timeout: it trips, then is reset
    r, ev = run(tmp_path, Faults(plc=PlcFaults(drop_at=T_FAULT, drop_for_s=drop)))
    assert_working_before_the_fault(r)
    # the answer to the request sent before the drop is taken in the first cycle after it (the blocks end a
    # request at the call after the one that sent it): from the next, no link
    assert not r.log.link[at(r, T_FAULT + 2 * r.log.period, T_FAULT + drop)].any()
    assert "fault plc_heartbeat" in r.service_log and "faults reset by the PLC" in r.service_log
    assert_recovers(r, ev, T_FAULT + 0.15, T_FAULT + drop)


def test_service_restarted_mid_run(tmp_path):
    r, ev = run(tmp_path, Faults(service_restart_at=T_FAULT, service_down_s=0.3), RESTART_FEED)
    assert_working_before_the_fault(r)
    assert len(r.stats) == 2 and all(s["status"] == "stopped" for s in r.stats)
    assert r.service_log.count("service running") == 2
    t, link = r.log.t, r.log.link
    lost = np.flatnonzero((t >= T_FAULT) & ~link)
    assert len(lost), "the PLC never lost the stopped service"
    t_lost = t[lost[0]]
    # on SIGTERM the old service ramped its correction down (status bit 3) instead of dropping it
    st = np.nan_to_num(value(r, "status_word")).astype(int)
    ramping = np.flatnonzero((t >= T_FAULT) & (t < t_lost) & link & (st & Status.RAMPING != 0))
    assert len(ramping), "the stopping service never ramped"
    stopping = np.flatnonzero((t >= t[ramping[0]]) & (t < t_lost) & link)
    assert np.all(np.diff(np.abs(corrections(r)[stopping]), axis=0) <= 1e-7), "the correction grew while stopping"
    relink = t[(t > t_lost) & link]
    assert len(relink), "the PLC never saw the new service"
    assert_recovers(r, ev, t_lost, relink[0])
