"""The payload table in the cycle: sets the PLC selects, a switch that blends the gravity term and the
static torque without a step, and an index with no set refused with a fault, the old set kept and one
log line. In-process `Cycle`s on explicit time; the running service's test is test_payload_service.py."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.payload import TruePayload
from hil.testing import write_config
from plc_link.contract import Command, Fault
from service.ati import Reading
from service.compensation import FastPredictor
from service.config import load_config
from service.errors import ServiceConfigError
from service.gravity import GravityConfig
from service.payloads import QUIET_AFTER
from service.pipeline import Cycle
from stiffness.kinematics.statics import PayloadConfig, statics_for
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import MODELS, ROOT

DT = 0.001
Q = [10.0, -80.0, 100.0, 20.0, 40.0, 30.0]
SPINDLE = {"index": 1, "name": "spindle + D20 mill", "mass_kg": 14.0, "cog_mm": [5.0, -3.0, 130.0],
           "bias": [2.0, -1.0, 4.0, 0.1, -0.05, 0.02], "tcp_mm": [0.0, 0.0, 300.0]}
GRIPPER = {"index": 3, "name": "gripper", "mass_kg": 6.5, "cog_mm": [0.0, 20.0, 80.0]}
RAMP_S = 0.2
RATE = 5.0                       # limits.max_rate_deg_s


def cycle_for(tmp_path, payloads=(SPINDLE, GRIPPER), **gravity) -> Cycle:
    over = {"gravity": {"tool": {"mass_kg": 0.0}, "bias": [0.0] * 6, "payloads": list(payloads),
                        "switch_ramp_s": RAMP_S, **gravity},
            "limits": {"max_rate_deg_s": RATE}, "faults": {"plc_heartbeat_timeout_ms": 0}}
    cfg = load_config(write_config(tmp_path, over))
    return Cycle.from_config(cfg, StiffnessModel.from_yaml(cfg.resolve(cfg.model.file)))


def reading_of(entry: dict, q_deg, cyc: Cycle) -> Reading:
    """What the sensor reads carrying ``entry`` at rest at ``q_deg`` (the HIL's own physics)."""
    cyc.compensator.predictor.kinematics(np.radians(q_deg))
    R_s = np.array(cyc.compensator.predictor.R_s)
    sec = GravityConfig(tool={"mass_kg": entry["mass_kg"], "cog_mm": entry["cog_mm"]},
                        bias=entry.get("bias", [0.0] * 6))
    return Reading((TruePayload(sec).wrench(R_s) + TruePayload(sec).bias).tolist(), 0, 0, False)


class Run:
    """Cycles on explicit time, recording the correction before and after limits and the wrench."""

    def __init__(self, cyc: Cycle, reading: Reading):
        self.cyc, self.reading, self.k = cyc, reading, 0
        self.out, self.dq, self.wrench, self.active = [], [], [], []

    def run(self, n: int, index: int, command: int = Command.ENABLE) -> None:
        for _ in range(n):
            self.cyc.step(self.k * DT, self.reading, [], command, 0, Q, False, index)
            self.out.append(list(self.cyc.correction))
            self.dq.append(list(self.cyc.dq_deg))
            self.wrench.append(list(self.cyc.wrench_sensor))
            self.active.append(self.cyc.signals().payload_active)
            self.k += 1


def test_duplicate_indices_and_bad_entries_are_refused_by_name(tmp_path):
    # sets named by their index (issue 27), the table described, never dumped
    with pytest.raises(ServiceConfigError, match=r"service\.yaml: gravity\.payloads has 2 entries: index 1 is used "
                       r"twice \(entries 1 and 2 of the table\); each set needs its own number$"):
        cycle_for(tmp_path, [SPINDLE, {**GRIPPER, "index": 1}])
    with pytest.raises(ServiceConfigError, match=r"gravity\.payloads\[index 0\]\.index = 0: .*greater than or equal to 1"):
        cycle_for(tmp_path, [{**SPINDLE, "index": 0}])
    with pytest.raises(ServiceConfigError, match=r"gravity\.payloads\[index 7\]\.mass_kg = -1\.0"):
        cycle_for(tmp_path, [GRIPPER, {**SPINDLE, "index": 7, "mass_kg": -1.0}])
    with pytest.raises(ServiceConfigError, match=r"gravity\.payloads\[index 1\]\.name is missing"):
        cycle_for(tmp_path, [{k: v for k, v in SPINDLE.items() if k != "name"}])
    with pytest.raises(ServiceConfigError, match=r"gravity\.payloads\[entry 2\]\.index is missing"):
        cycle_for(tmp_path, [SPINDLE, {k: v for k, v in GRIPPER.items() if k != "index"}])


def test_a_switch_under_load_blends_the_gravity_term_and_the_correction_never_steps(tmp_path, caplog):
    """The sensor carries the spindle; the service compensates nothing (set 0) and corrects for its weight
    as a load. Selecting set 1 moves the wrench linearly to zero over the ramp: each cycle's step of the
    correction before limits is the ramp's share, below the limiter's rate, and the weight is gone after."""
    cyc = cycle_for(tmp_path)
    run = Run(cyc, reading_of(SPINDLE, Q, cyc))
    run.run(1500, 0)                                     # settled on the load (the limiter's rate is slow)
    w0, dq0 = np.array(run.wrench[-1]), np.array(run.dq[-1])
    assert np.linalg.norm(w0[:3]) > 100.0 and np.allclose(run.out[-1], dq0, atol=1e-12)
    with caplog.at_level(logging.INFO, logger="stiffcomp.payload"):
        run.run(int(RAMP_S / DT) + 50, 1)
    lines = [r.getMessage() for r in caplog.records if "payload switch" in r.getMessage()]
    assert lines == [("payload switch (payload_index): 0 'gravity bodies' (0 kg) -> 1 'spindle + D20 mill' "
                     "(14 kg, TCP [0, 0, 300] mm) over gravity.switch_ramp_s = 0.2 s")]
    n = int(RAMP_S / DT) + 50
    w, dq, out = (np.array(a[-n - 1:]) for a in (run.wrench, run.dq, run.out))
    s = np.clip(np.arange(n + 1) * DT / RAMP_S, 0.0, 1.0)           # the ramp's share after each cycle
    np.testing.assert_allclose(w, (1 - s)[:, None] * w0, atol=1e-9)        # exactly the blend
    assert np.abs(np.diff(dq, axis=0)).max() <= np.abs(dq0).max() * DT / RAMP_S * 1.01
    assert np.abs(np.diff(out, axis=0)).max() <= RATE * DT + 1e-12
    assert np.abs(w[-1]).max() < 1e-9 and np.abs(dq[-1]).max() < 1e-12      # the weight is removed
    assert run.active[-n - 1] == 0 and run.active[-1] == 1
    assert run.active.index(1) == len(run.active) - n - 1 + round(RAMP_S / DT)   # when the ramp ends


def test_a_missing_index_is_refused_keeps_the_set_and_logs_once(tmp_path, caplog):
    cyc = cycle_for(tmp_path)
    run = Run(cyc, reading_of(GRIPPER, Q, cyc))
    run.run(int(RAMP_S / DT) + 10, 3)
    assert run.active[-1] == 3 and cyc.faults.word == 0
    before = np.array(run.wrench[-1])
    caplog.clear()
    with caplog.at_level(logging.INFO):
        run.run(300, 7)
        refusals = [r for r in caplog.records if "payload_index = 7" in r.getMessage()]
        assert len(refusals) == 1 and refusals[0].levelno == logging.ERROR
        assert "names no payload set (gravity.payloads has 0, 1, 3); set 3 'gripper' (6.5 kg) stays in use" in \
            refusals[0].getMessage()
        assert cyc.faults.word == Fault.PAYLOAD_INVALID and run.active[-1] == 3
        np.testing.assert_allclose(run.wrench[-1], before, atol=1e-12)   # the old set is kept
        assert run.out[-1] == [0.0] * 6                                  # the safe state, as every fault
        run.run(50, 8)                                                   # another refusal, still latched
        assert sum("payload_index = 8" in r.getMessage() for r in caplog.records) == 1
        run.run(5, 8, Command.ENABLE | Command.RESET)                    # a reset, the cause persists
        assert cyc.faults.word == Fault.PAYLOAD_INVALID
        run.run(5, 3)
        run.run(5, 3, Command.ENABLE | Command.RESET)                    # a reset with a valid index clears
        assert cyc.faults.word == 0 and run.active[-1] == 3
    assert not [r for r in caplog.records if "payload switch" in r.getMessage()]   # 3 stayed in use throughout


def test_a_tare_offset_stays_across_a_switch(tmp_path):
    cyc = cycle_for(tmp_path)
    drift = np.array([1.5, -0.5, 2.0, 0.02, 0.01, -0.03])
    r = reading_of(SPINDLE, Q, cyc)
    run = Run(cyc, Reading((np.array(r.wrench) + drift).tolist(), 0, 0, False))
    run.run(int(RAMP_S / DT) + 10, 1)
    np.testing.assert_allclose(run.wrench[-1], drift, atol=1e-9)
    run.run(3, 1, Command.ENABLE | Command.TARE)
    run.run(3, 1)
    np.testing.assert_allclose(run.wrench[-1], 0.0, atol=1e-9)
    g = reading_of(GRIPPER, Q, cyc)
    run.reading = Reading((np.array(g.wrench) + drift).tolist(), 0, 0, False)
    run.run(int(RAMP_S / DT) + 10, 3)                 # the tool changed, the sensor's drift did not
    np.testing.assert_allclose(run.wrench[-1], 0.0, atol=1e-6)


def test_a_reload_ramps_the_set_in_use_to_its_new_values_and_refuses_a_set_that_is_gone(tmp_path, caplog):
    cyc = cycle_for(tmp_path)
    run = Run(cyc, reading_of({**SPINDLE, "mass_kg": 15.0}, Q, cyc))
    run.run(int(RAMP_S / DT) + 10, 1)
    assert np.linalg.norm(run.wrench[-1][:3]) > 5.0        # 1 kg missing
    section = cyc.compensator.payloads
    section.reload(GravityConfig(payloads=[{**SPINDLE, "mass_kg": 15.0}], switch_ramp_s=0.1))
    run.run(110, 1)
    assert np.abs(run.wrench[-1]).max() < 1e-9 and cyc.faults.word == 0
    with caplog.at_level(logging.ERROR):
        section.reload(GravityConfig(payloads=[GRIPPER]))
        run.run(5, 1)
    assert cyc.faults.word == Fault.PAYLOAD_INVALID and run.active[-1] == 1
    assert sum("payload_index = 1 names no payload set" in r.getMessage() for r in caplog.records) == 1


MASSES = ROOT / "config" / "robots" / "kr125_masses.yaml"


@pytest.fixture(scope="module")
def loaded_predictor():
    d = StiffnessModel.from_yaml(MODELS / "kr125_6dof.yaml").to_dict()
    d["robot"] = str(MASSES)
    d["effects"] = d["effects"] + [{"effect": "backlash", "joint": 2, "lost_motion_deg": 0.02, "width_Nm": 40.0}]
    return StiffnessModel.from_dict(d, "kr125_6dof on kr125_masses")


@settings(max_examples=25, deadline=None)
@given(m=st.floats(0.0, 120.0), cog=st.lists(st.floats(-300.0, 300.0), min_size=3, max_size=3),
       q=st.lists(st.floats(-60.0, 30.0), min_size=6, max_size=6), s=st.floats(0.0, 1.0))
def test_the_static_torque_follows_a_payload_change_and_blends_linearly(loaded_predictor, m, cog, q, s):
    """carry_payload(m, m c) gives the tau_s a Statics built for that payload from scratch gives, and a
    blend of two payloads' (m, m c) gives the same blend of their tau_s (what a switch's ramp relies on)."""
    fp = FastPredictor(loaded_predictor)
    fp.carry(40.0, [0.0, 0.0, 0.1], [0.0, 0.0, -9.81])
    fp.kinematics(np.radians(q))
    tau_old = np.array(fp.tau_s)
    mc_old, mc_new = 40.0 * np.array([0.0, 0.0, 0.1]), m * np.array(cog) / 1000.0
    fp.carry_payload(m, mc_new)
    fresh = statics_for(loaded_predictor.robot, PayloadConfig(mass_kg=m, cog_mm=cog), [0.0, 0.0, -9.81])
    np.testing.assert_allclose(fp.tau_s, fresh.total_at(np.radians(q)), rtol=1e-10, atol=1e-8)
    tau_new = np.array(fp.tau_s)
    fp.carry_payload((1 - s) * 40.0 + s * m, (1 - s) * mc_old + s * mc_new)
    np.testing.assert_allclose(fp.tau_s, (1 - s) * tau_old + s * tau_new, rtol=1e-9, atol=1e-8)


def test_a_plc_cycling_through_missing_indices_logs_a_bounded_number_of_lines(tmp_path, caplog):
    cyc = cycle_for(tmp_path)
    run = Run(cyc, reading_of(SPINDLE, Q, cyc))
    with caplog.at_level(logging.INFO):
        for index in range(100, 400):
            run.run(1, index)
    lines = [r.getMessage() for r in caplog.records if "names no payload set" in r.getMessage()]
    assert len(lines) == 1 + QUIET_AFTER and lines[-1].endswith("further refusals are not logged until a reset")
    assert cyc.faults.word == Fault.PAYLOAD_INVALID and run.active[-1] == 0
