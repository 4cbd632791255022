"""Every fault: injected, its bit set, one log line, the correction ramps to zero, reset resumes.

The compensator is driven exactly as the live loop drives it, with the time as an argument and a
replay source paced "fast" (one sample per cycle), so these tests do not depend on the clock.
"""

from __future__ import annotations

import logging
import math

import numpy as np
import pytest

from hil.demo_log import write_log
from hil.testing import write_config
from plc_link.contract import Command, Fault, Status
from service.ati import AtiProtocol
from service.config import load_config
from service.pipeline import Cycle
from service.sources import make_source
from stiffness.files.yaml_schema import deep_update
from stiffness.model.stiffness_model import StiffnessModel

DT = 1e-3
Q = [10.0, -80.0, 100.0, 20.0, 40.0, 30.0]
LOAD = np.array([300.0, -200.0, 400.0, 15.0, 10.0, 5.0])
N_OK, N_FAULT = 400, 400          # healthy cycles, then cycles with the fault present
INJECT_AT = N_OK


def build(tmp_path, samples: int = 2000, status=None, extra=None, wrench=None, overrides=None):
    w = np.tile(LOAD, (samples, 1)) if wrench is None else wrench
    log = tmp_path / "ft.blf"
    write_log(log, w, status=status, extra=extra)
    over = {"source": {"replay": {"file": str(log), "pacing": "fast", "loop": False}},
            "gravity": {"tool": {"mass_kg": 0.0}, "bias": [0.0] * 6},
            "limits": {"max_rate_deg_s": 50.0, "fault_ramp_s": 0.1}}
    deep_update(over, overrides or {})
    cfg = load_config(write_config(tmp_path, over))
    model = StiffnessModel.from_yaml(cfg.resolve(cfg.model.file))
    return cfg, Cycle.from_config(cfg, model), make_source(cfg)


class Driver:
    """Run cycles with explicit time, command, heartbeat, q and overrun flag."""

    def __init__(self, comp, src):
        self.comp, self.src, self.k = comp, src, 0
        self.history = []

    def run(self, n, command=Command.ENABLE, q=Q, hb_frozen=False, overrun=False):
        for _ in range(n):
            t = self.k * DT
            reading, errors = self.src.poll(t)
            hb = 7 if hb_frozen else self.k & 0xFFFF
            out = self.comp.step(t, reading, errors, command, hb, q, overrun)
            self.history.append(list(out))
            self.k += 1
        return np.array(self.history[-n:])


def frames_at(k, arb, data):
    return [(k, arb, data)]


INT16_MAX_FORCE = 32767 / 10.0


def case(name):
    """(build kwargs, per-phase driver kwargs while the fault is present)."""
    status = np.zeros(2000, dtype=int)
    if name == "sensor_timeout":
        return {"samples": INJECT_AT}, {}                     # the log ends: the sensor goes silent
    if name == "sensor_status":
        status[INJECT_AT:INJECT_AT + 5] = 0x8001
        return {"status": status}, {}
    if name == "sensor_saturated":
        w = np.tile(LOAD, (2000, 1))
        w[INJECT_AT, 0] = 1e5                                 # clipped to INT16
        return {"wrench": w}, {}
    if name == "value_invalid":
        w = np.tile(LOAD, (2000, 1))
        w[INJECT_AT, 2] = 2400.0                              # above max_force_N = 2000
        return {"wrench": w, "overrides": {"source": {"max_force_N": 2000.0}}}, {}
    if name == "value_invalid_q":
        return {}, {"q": [math.nan] + Q[1:]}
    if name == "value_invalid_q_inf":
        return {}, {"q": Q[:3] + [math.inf] + Q[4:]}
    if name == "can_frame":
        p = AtiProtocol()
        return {"extra": [(INJECT_AT, p.id_1, b"\x01\x02\x03")]}, {}
    if name == "can_frame_unknown_id":
        return {"extra": [(INJECT_AT, 0x02A, b"\x00" * 8)]}, {}
    if name == "plc_heartbeat":
        return {}, {"hb_frozen": True}
    if name == "overrun":
        return {}, {"overrun": True}
    if name == "joint_limits":
        return {}, {"q": [10.0, -80.0, 100.0, 20.0, 140.0, 30.0]}   # q5 limit is 130
    if name == "command_invalid":
        return {}, {"command": 0xFFFF}                         # every undefined bit set, tare and reset too
    raise KeyError(name)


FAULT_OF = {"value_invalid_q": "value_invalid", "value_invalid_q_inf": "value_invalid",
            "can_frame_unknown_id": "can_frame"}
CASES = ["sensor_timeout", "sensor_status", "sensor_saturated", "value_invalid", "value_invalid_q",
         "value_invalid_q_inf",
         "can_frame", "can_frame_unknown_id", "plc_heartbeat", "overrun", "joint_limits", "command_invalid"]


@pytest.mark.parametrize("name", CASES)
def test_fault_trips_ramps_to_zero_and_latches_until_reset(tmp_path, caplog, name):
    build_kw, fault_kw = case(name)
    fault = FAULT_OF.get(name, name)
    cfg, comp, src = build(tmp_path, **build_kw)
    drv = Driver(comp, src)
    healthy = drv.run(N_OK)
    assert comp.faults.word == 0 and comp.status_word & Status.ACTIVE
    start = healthy[-1]
    assert np.abs(start).max() > 1e-3                      # a real correction is being output
    with caplog.at_level(logging.ERROR, logger="stiffcomp.faults"):
        faulted = drv.run(N_FAULT, **fault_kw)
    assert comp.faults.word & Fault.from_kind(fault)
    assert comp.status_word & Status.FAULTED and not comp.status_word & Status.ACTIVE
    lines = [r.getMessage() for r in caplog.records if r.getMessage().startswith(f"fault {fault}:")]
    assert len(lines) == 1
    # safe state: ramps to zero within fault_ramp_s and never jumps
    path = np.vstack([start, faulted])
    assert np.all(np.abs(np.diff(path, axis=0)) <= np.abs(start) / cfg.limits.fault_ramp_s * DT + 1e-9)
    assert np.all(faulted[-1] == 0.0)
    if name == "sensor_timeout":
        return                                            # the log has ended: nothing to resume from
    # the cause is gone, but the fault is latched ...
    latched = drv.run(50)
    assert np.all(latched == 0.0) and comp.faults.word
    # ... until the PLC resets it (rising edge of bit 2)
    drv.run(1, command=Command.ENABLE | Command.RESET)
    resumed = drv.run(200)
    assert comp.faults.word == 0
    assert np.abs(resumed[-1]).max() > 1e-3


def test_disabling_ramps_to_zero_without_a_fault(tmp_path):
    _, comp, src = build(tmp_path)
    drv = Driver(comp, src)
    drv.run(300)
    out = drv.run(300, command=0)
    assert comp.faults.word == 0 and np.all(out[-1] == 0.0)


def test_correction_matches_the_prediction_once_settled(tmp_path):
    cfg, comp, src = build(tmp_path)
    drv = Driver(comp, src)
    drv.run(500)
    np.testing.assert_allclose(comp.correction, comp.dq_deg, atol=1e-12)
    assert np.abs(comp.dq_deg).max() <= cfg.limits.max_correction_deg[0]
    # the wrench was seen in sensor axes and reported in base axes with the same magnitude
    assert np.isclose(np.linalg.norm(comp.wrench_base[:3]), np.linalg.norm(LOAD[:3]), rtol=1e-3)


def test_reset_pulses_while_the_sensor_is_silent_never_go_active(tmp_path):
    """A reset clears only faults whose cause is gone: the cycle carrying the edge stays safe."""
    _, comp, src = build(tmp_path, samples=INJECT_AT)
    drv = Driver(comp, src)
    drv.run(N_OK)
    drv.run(N_FAULT)                                      # the log has ended: sensor_timeout, ramped to zero
    assert comp.faults.word & Fault.SENSOR_TIMEOUT
    assert np.all(np.array(comp.correction) == 0.0)
    for _ in range(20):                                   # a PLC pulsing reset
        out = drv.run(1, command=Command.ENABLE | Command.RESET)
        assert comp.faults.word & Fault.SENSOR_TIMEOUT
        assert not comp.status_word & Status.ACTIVE and np.all(out == 0.0)
        out = drv.run(2)
        assert comp.faults.word and not comp.status_word & Status.ACTIVE and np.all(out == 0.0)
