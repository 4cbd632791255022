"""Reload without a restart, in process: what `service.reload.prepare` accepts, refuses and swaps in.

The cycle is driven as the live loop drives it (`Cycle.step` with explicit time); the swap runs between
two cycles as `Service.work` runs it. The running service's tests are in test_reload_service.py.
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.testing import scaled_model_file, write_config
from plc_link.contract import Command
from service.config import load_config
from service.filters import SosLowPass
from service.pipeline import Cycle
from service.reload import Outcome, Prepared, prepare
from service.sources import make_source
from service.sources.replay import write_log
from stiffness.files.yaml_schema import deep_update, dump_yaml, read_yaml
from stiffness.model.stiffness_model import StiffnessModel

DT = 1e-3
Q = [10.0, -80.0, 100.0, 20.0, 40.0, 30.0]
LOAD = np.array([300.0, -200.0, 400.0, 15.0, 10.0, 5.0])
NOISE = np.array([2.0, 2.0, 2.0, 0.2, 0.2, 0.2])


def rewrite(path, changes: dict) -> None:
    data = read_yaml(path)
    deep_update(data, changes)
    path.write_text(dump_yaml(data, sort_keys=False))


class Rig:
    """A cycle, its replay source (a constant load with noise) and its config file, stepped in time."""

    def __init__(self, tmp_path, overrides: dict | None = None, samples: int = 6000):
        rng = np.random.default_rng(7)
        log = tmp_path / "ft.blf"
        write_log(log, LOAD + NOISE * rng.standard_normal((samples, 6)))
        over = {"source": {"replay": {"file": str(log), "pacing": "fast", "loop": True}},
                "gravity": {"tool": {"mass_kg": 0.0}, "bias": [0.0] * 6},
                "limits": {"max_rate_deg_s": 50.0, "fault_ramp_s": 0.1}}
        deep_update(over, overrides or {})
        self.path = write_config(tmp_path, over)
        self.cfg = load_config(self.path)
        self.model = StiffnessModel.from_yaml(self.cfg.resolve(self.cfg.model.file))
        self.rmap = self.cfg.register_map()
        self.cycle = Cycle.from_config(self.cfg, self.model)
        self.source = make_source(self.cfg)
        self.k = 0
        self.payload_index = 0          # what the PLC writes to payload_index

    def run(self, n: int) -> dict[str, np.ndarray]:
        rows = {"wrench": [], "deflection": [], "dq": [], "correction": []}
        for _ in range(n):
            t = self.k * DT
            reading, errors = self.source.poll(t)
            self.cycle.step(t, reading, errors, int(Command.ENABLE), self.k & 0xFFFF, Q, False, self.payload_index)
            c = self.cycle
            for key, v in (("wrench", c.wrench_base), ("deflection", c.deflection), ("dq", c.dq_deg),
                           ("correction", c.correction)):
                rows[key].append(list(v))
            self.k += 1
        return {k: np.array(v) for k, v in rows.items()}

    def reload(self, changes: dict) -> Prepared | Outcome:
        rewrite(self.path, changes)
        got = prepare(self.cfg, self.model, self.rmap, self.cycle)
        if isinstance(got, Prepared):
            got.swap(self.cycle, self.source)
            self.cfg, self.model = got.cfg, got.model
        return got

    def close(self) -> None:
        self.source.close()


@pytest.fixture
def rig(tmp_path):
    made = []

    def make(**kw) -> Rig:
        made.append(Rig(tmp_path, **kw))
        return made[-1]

    yield make
    for r in made:
        r.close()


@settings(max_examples=40, deadline=None)
@given(kind=st.sampled_from(["butterworth", "bessel", "none"]), order=st.integers(1, 8),
       cut_old=st.floats(1.0, 450.0), cut_new=st.floats(1.0, 450.0),
       x=st.lists(st.floats(-2000.0, 2000.0), min_size=6, max_size=6))
def test_a_filter_taking_over_a_settled_one_continues_its_output_without_a_step(kind, order, cut_old, cut_new, x):
    old = SosLowPass.design("butterworth", 2, cut_old, 1000.0)
    old.state = old.steady_state(x)
    y_old = old.update(x)
    new = SosLowPass.design(kind, order, cut_new, 1000.0)
    new.continue_from(old)
    for _ in range(3):
        assert new.update(x) == pytest.approx(y_old, rel=1e-9, abs=1e-9)


def test_a_reload_with_a_new_cutoff_shows_no_step_in_the_filtered_wrench_beyond_the_noise(rig):
    r = rig()
    before = r.run(1500)["wrench"]
    noise_step = np.abs(np.diff(before[500:], axis=0)).max(axis=0)      # settled: cycle-to-cycle noise
    got = r.reload({"filter": {"cutoff_hz": 20.0, "order": 4}})
    assert isinstance(got, Prepared), got
    after = r.run(500)["wrench"]
    step = np.abs(after[0] - before[-1])
    assert np.all(step <= noise_step), (step, noise_step)
    assert np.abs(np.diff(after, axis=0)).max(axis=0) @ [1, 1, 1, 0, 0, 0] > 0     # the wrench goes on
    # the new filter passes less noise: it is the one in place
    assert np.abs(np.diff(after[100:], axis=0)).max(axis=0)[2] < noise_step[2]
    # a filter started afresh would step by the whole load: the check above can fail
    assert np.abs(LOAD[:3]).min() > 10 * noise_step[:3].max()


def test_an_invalid_file_changes_nothing_and_names_file_key_and_range(rig):
    r = rig()
    r.run(200)
    filt, limiter = r.cycle.compensator.filter, r.cycle.compensator.limiter.rate
    got = r.reload({"filter": {"cutoff_hz": 900.0}, "limits": {"max_rate_deg_s": 1.0}})
    assert isinstance(got, Outcome) and not got.accepted
    assert got.message.startswith(f"reload of {r.path} refused, nothing changed: filter.cutoff_hz = 900")
    assert "500" in got.message
    assert r.cycle.compensator.filter is filt and r.cycle.compensator.limiter.rate == limiter
    assert r.cycle.reloads == 0


@pytest.mark.parametrize("changes, key", [
    ({"plc": {"port": 1}}, "plc.port"),
    ({"cycle": {"period_ms": 2.0}}, "cycle.period_ms"),
    ({"monitoring": {"port": 2}}, "monitoring.port"),
    ({"source": {"max_force_N": 2000.0}}, "source.max_force_N"),
    ({"dynamics": {"enabled": True, "predictor": {}}}, "dynamics.enabled"),       # issue 26: its states start with the cycle
    ({"accelerometer": {"timeout_ms": 50.0}}, "accelerometer.timeout_ms"),      # its supervision and bias too
    ({"robot": {"interface": "kuka_rsi"}}, "robot.interface"),          # the robot road listens from the start
    ({"robot": {"kuka_rsi": {"correction": "relative"}}}, "robot.kuka_rsi.correction"),
])
def test_a_change_only_a_restart_applies_refuses_the_whole_reload_by_name(rig, changes, key):
    r = rig()
    rate = r.cycle.compensator.limiter.rate
    got = r.reload({**changes, "limits": {"max_rate_deg_s": 1.0}})
    assert isinstance(got, Outcome) and not got.accepted
    assert key in got.message and "restart" in got.message and "limits" not in got.message
    assert r.cycle.compensator.limiter.rate == rate and r.cycle.reloads == 0


def test_a_reloaded_payload_table_ramps_the_set_in_use_and_a_new_set_becomes_selectable(rig):
    """gravity goes to the payload switch: the set in use (index 0, the section's bodies) ramps to its new
    mass over switch_ramp_s, without a step in the wrench; a set the reload adds is then selectable."""
    r = rig(overrides={"gravity": {"switch_ramp_s": 0.05}})
    before = r.run(200)["wrench"]
    got = r.reload({"gravity": {"tool": {"mass_kg": 5.0},
                                "payloads": [{"index": 2, "name": "probe", "mass_kg": 1.0,
                                              "cog_mm": [0.0, 0.0, 100.0], "bias": [0.0] * 6}]}})
    assert isinstance(got, Prepared) and "gravity.tool.mass_kg" in got.changes
    assert got.changes["gravity.payloads[index 2]"][0] is None          # the set by its index, as one key
    after = r.run(200)["wrench"]
    w = np.vstack([before[-50:], after])
    steps = np.abs(np.diff(w[:, :3], axis=0)).max(0)
    weight = 5.0 * 9.81
    assert steps.max() < weight / 10, steps              # 50 cycles of ramp: about weight/50 per cycle
    assert abs(np.linalg.norm(after[-50:, :3].mean(0) - before[-50:, :3].mean(0)) - weight) < 1.0
    payloads = r.cycle.compensator.payloads
    assert payloads.active.index == 0 and payloads.active.mass_kg == pytest.approx(5.0)
    assert 2 in payloads.sets


def test_a_change_of_gravitys_direction_needs_a_restart(rig):
    r = rig()
    got = r.reload({"gravity": {"g_mps2": [0.0, 0.0, 9.81]}, "limits": {"max_rate_deg_s": 1.0}})
    assert isinstance(got, Outcome) and not got.accepted
    assert "gravity.g_mps2" in got.message and "restart" in got.message and r.cycle.reloads == 0


def test_live_keys_land_in_the_running_stages_and_count_one_reload(rig):
    r = rig()
    r.run(100)
    got = r.reload({"limits": {"max_correction_deg": 0.3, "max_rate_deg_s": 2.0, "fault_ramp_s": 0.5},
                    "faults": {"sensor_timeout_ms": 20.0, "plc_heartbeat_timeout_ms": 0, "overrun_trip_count": 5},
                    "tare": {"max_force_N": 50.0}, "filter": {"spike": {"max_step_N": 100.0, "max_held": 1}}})
    assert isinstance(got, Prepared), got
    c, s = r.cycle.compensator, r.cycle.supervisor
    assert c.limiter.max == [0.3] * 6 and c.limiter.rate == [2.0] * 6 and c.limiter.ramp_s == 0.5
    assert r.source.timeout_s == 0.02 and s.hb_timeout == 0 and s.overrun_trip == 5
    assert c.tare_max == 50.0 and c.spikes.max_step[:3] == [100.0] * 3 and c.spikes.max_held == 1
    assert set(got.changes) == {"limits.max_correction_deg", "limits.max_rate_deg_s", "limits.fault_ramp_s",
                                "faults.sensor_timeout_ms", "faults.plc_heartbeat_timeout_ms",
                                "faults.overrun_trip_count", "tare.max_force_N", "filter.spike.max_step_N",
                                "filter.spike.max_held"}
    assert got.changes["limits.max_rate_deg_s"] == ([50.0] * 6, [2.0] * 6)
    assert r.cycle.reloads == 1 and r.cycle.signals().reload_count == 1


def scaled_model(r: Rig, tmp_path, factor: float, extra: list | None = None) -> str:
    return str(scaled_model_file(r.cfg.resolve(r.cfg.model.file), factor,
                                 tmp_path / f"model_{factor:g}_{len(extra or [])}.yaml", extra))


def test_a_model_with_the_same_structure_ramps_from_the_old_prediction_to_the_new(rig, tmp_path):
    r = rig()
    old = r.run(600)
    n = round(r.cfg.limits.fault_ramp_s / DT)
    got = r.reload({"model": {"file": scaled_model(r, tmp_path, 1.5)}})
    assert isinstance(got, Prepared), got
    assert any(k.startswith("model.file:joint_spring@joint2") for k in got.changes)
    ramp = r.run(n + 200)
    d_old, d_new = old["deflection"][-100:].mean(0), ramp["deflection"][-100:].mean(0)
    assert np.allclose(d_new, 1.5 * d_old, rtol=0.02)             # the new model's prediction, once ramped
    # no step: each cycle moves at most by its share of the change, plus the load's noise
    steps = np.abs(np.diff(np.vstack([old["deflection"][-1:], ramp["deflection"][:n]]), axis=0))
    noise = np.abs(np.diff(old["deflection"][-300:], axis=0)).max(0)
    assert np.all(steps <= np.abs(d_new - d_old) / n * 1.05 + 1.5 * noise)
    assert np.abs(d_new - d_old).max() > 20 * (np.abs(d_new - d_old) / n + noise).max()     # a jump would fail
    # and the correction never moves faster than its rate limit
    assert np.abs(np.diff(ramp["correction"], axis=0)).max() <= r.cfg.limits.max_rate_deg_s[0] * DT * (1 + 1e-9)
    comp = r.cycle.compensator
    assert comp.predictor is not None and type(comp.predictor).__name__ == "FastPredictor"
    assert comp.payloads.predictor is comp.predictor        # a later payload switch reaches the new model


def test_a_model_with_another_structure_is_refused_by_name(rig, tmp_path):
    r = rig()
    extra = [{"effect": "backlash", "joint": 3, "lost_motion_deg": 0.01, "width_Nm": 30.0}]
    got = r.reload({"model": {"file": scaled_model(r, tmp_path, 1.0, extra)}})
    assert isinstance(got, Outcome) and not got.accepted, got
    assert "model.file:effects" in got.message and "restart" in got.message


PROBE = {"index": 3, "name": "probe", "mass_kg": 1.0, "cog_mm": [0.0, 0.0, 100.0], "bias": [0.0] * 6}
GRIPPER = {"index": 4, "name": "gripper", "mass_kg": 2.0, "cog_mm": [0.0, 0.0, 80.0], "bias": [0.0] * 6}


def test_a_table_without_the_set_the_plc_selects_is_refused_naming_it_until_the_plc_moves(rig):
    """Issue 27, item 4: the reload used to be accepted and latch payload_invalid, ramping the correction to
    zero, with "accepted" in its own line. Now it is refused like any invalid reload (`stiffcomp reload`
    exits 1 on it), nothing changed, the set named; after the PLC moves to a set that stays, it is taken."""
    r = rig(overrides={"gravity": {"switch_ramp_s": 0.01, "payloads": [PROBE, GRIPPER]}})
    r.payload_index = 3
    r.run(100)
    payloads = r.cycle.compensator.payloads
    assert payloads.active.index == 3 and r.cycle.faults.word == 0
    got = r.reload({"gravity": {"payloads": [GRIPPER]}})
    assert isinstance(got, Outcome) and not got.accepted
    assert got.message == (f"reload of {r.path} refused, nothing changed: gravity.payloads[index 3] removed, but the "
                           "PLC's payload_index = 3 selects it (set 3 'probe' (1 kg)): switch the PLC to a set that "
                           "stays, then reload")
    r.run(50)
    assert sorted(payloads.sets) == [0, 3, 4] and payloads.active.index == 3
    assert r.cycle.faults.word == 0 and r.cycle.reloads == 0 and any(r.cycle.correction)
    # the PLC moves to set 4, which the file keeps: the same file is taken, and set 3 is gone
    r.payload_index = 4
    r.run(50)
    got = r.reload({})
    assert isinstance(got, Prepared), got
    (key, (old, new)), = got.changes.items()
    assert key == "gravity.payloads[index 3]" and old["name"] == "probe" and new is None
    r.run(20)
    assert sorted(payloads.sets) == [0, 4] and payloads.active.index == 4 and r.cycle.faults.word == 0


def test_a_reload_line_names_the_changed_keys_of_a_table_never_a_dump(rig):
    """Smaller item: the line used to show `gravity.payloads [] → [{'bias': [...], …`."""
    from service.reload import describe

    r = rig(overrides={"gravity": {"payloads": [PROBE]}})
    got = r.reload({"gravity": {"payloads": [{**PROBE, "mass_kg": 1.5}, GRIPPER]}})
    assert isinstance(got, Prepared)
    line = describe(got.changes)
    assert line == "gravity.payloads[index 3].mass_kg 1.0 → 1.5, gravity.payloads[index 4] added"
    assert "{" not in line and "'bias'" not in line
