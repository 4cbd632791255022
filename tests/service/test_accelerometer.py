"""The flange accelerometer in the service (`service.accelerometer`, docs/accelerometer.md).

* the arm's acceleration comes back in base axes for any mounting, pose, gravity and bias: a box that reads
  f = R^T (a - g) + b, tared at rest, gives a (hypothesis);
* a box whose count stands still is ``accelerometer_frozen`` after ``timeout_ms`` (``accelerometer_missing``
  when it never moved), logged by name once, the acceleration 0 and status bit 8 clear, and the correction
  unchanged (the force alone); the samples coming again end it;
* through the cycle: the signals and the status word carry it, on the Python and the compiled path alike;
* the config: enabled with a register map that lacks its values refuses to start, naming them;
* a replay file (``accelerometer.replay``): the PLC's samples recorded at the cycles they arrived and replayed
  give the same acceleration cycle by cycle (hypothesis), the file's end is a frozen box, a bad file is named by
  line, and a replay needs no register of the map.
"""

from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from hil.testing import CONFIG, model_with
from plc_link.contract import FROM_PLC, Command, FromPlc, Status
from service.accelerometer import FROZEN, MISSING, Accelerometer, AccelerometerConfig, BoxReplay
from service.app import Service
from service.ati import Reading
from service.config import ServiceConfig, load_config
from service.errors import ServiceConfigError
from service.pipeline import Cycle
from service.startup import check_plc_values
from stiffness.errors import DataError

G = np.array([0.0, 0.0, -9.81])
Q = [10.0, -70.0, 95.0, 15.0, 40.0, -20.0]
W = [300.0, -200.0, 150.0, 5.0, 2.0, 1.0]


def record(f, count: int) -> FromPlc:
    return FromPlc(**{v.name: 0.0 for v in FROM_PLC})._replace(acc_x=f[0], acc_y=f[1], acc_z=f[2], acc_samples=count)


def box(R: np.ndarray, a: np.ndarray, bias: np.ndarray, g: np.ndarray = G) -> np.ndarray:
    """What the box reads: the specific force along its axes, plus its bias."""
    return R.T @ (a - g) + bias


angles = st.lists(st.floats(-180.0, 180.0), min_size=3, max_size=3)
vectors = st.lists(st.floats(-20.0, 20.0), min_size=3, max_size=3)


@settings(max_examples=60, deadline=None)
@given(mount=angles, pose=angles, bias=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3), a=vectors)
def test_the_arms_acceleration_comes_back_for_any_mounting_pose_and_bias(mount, pose, bias, a):
    acc = Accelerometer(AccelerometerConfig(enabled=True, mount={"rpy_deg": mount}), G)
    R_s = Rotation.from_euler("xyz", pose, degrees=True).as_matrix()
    R = R_s @ acc.R_m
    b = np.array(bias)
    acc.update(0.0, record(box(R, np.zeros(3), b), 0), R_s, False)
    acc.update(0.001, record(box(R, np.zeros(3), b), 1), R_s, True)           # at rest: the tare takes the bias
    assert np.allclose(acc.acceleration, 0.0, atol=1e-9)
    acc.update(0.002, record(box(R, np.array(a), b), 2), R_s, False)
    assert acc.ok and np.allclose(acc.acceleration, a, atol=1e-9)


def test_a_frozen_box_is_named_once_reads_zero_and_recovers(caplog):
    acc = Accelerometer(AccelerometerConfig(enabled=True, timeout_ms=20.0), G)
    R = np.eye(3)
    moving = box(R, np.array([0.5, 0.0, 0.0]), np.zeros(3))
    caplog.set_level(logging.INFO, logger="stiffcomp.service")
    states = []
    for k in range(200):
        count = k if k < 50 or k >= 150 else 50             # frozen from 50 ms to 150 ms
        acc.update(0.001 * k, record(moving, count), R, False)
        states.append((acc.ok, acc.condition, acc.acceleration[0]))
    ok = np.array([s[0] for s in states])
    assert ok[1:50].all() and not ok[71:150].any() and ok[150:].all()
    assert ok[50:70].all()                                  # within timeout_ms the last value stands
    assert {s[1] for s in states[71:150]} == {FROZEN} and all(s[2] == 0.0 for s in states[71:150])
    assert all(abs(s[2] - 0.5) < 1e-12 for s in states[150:])
    named = [r.getMessage() for r in caplog.records if FROZEN in r.getMessage()]
    assert len(named) == 2 and "has not moved for 2" in named[0] and "ended" in named[1]


def test_a_box_that_never_delivers_is_missing_and_a_value_not_finite_is_frozen(caplog):
    acc = Accelerometer(AccelerometerConfig(enabled=True, timeout_ms=10.0), G)
    caplog.set_level(logging.WARNING, logger="stiffcomp.service")
    for k in range(30):
        acc.update(0.001 * k, record([0.0, 0.0, 9.81], 7), np.eye(3), False)
    assert not acc.ok and acc.condition == MISSING
    for k in range(30, 40):
        acc.update(0.001 * k, record([0.0, 0.0, 9.81], k), np.eye(3), False)
    assert acc.ok and acc.condition is None
    for k in range(40, 60):
        acc.update(0.001 * k, record([float("nan"), 0.0, 9.81], k), np.eye(3), False)
        assert not acc.ok and acc.condition == FROZEN and not np.isnan(acc.acceleration).any()
    assert any("not finite" in r.getMessage() for r in caplog.records)
    for k in range(60, 90):                                 # beyond any box's range: no reading either
        acc.update(0.001 * k, record([1e6, 0.0, 9.81], k), np.eye(3), False)
        assert not acc.ok and np.all(acc.acceleration == 0.0)


def config_with_accelerometer(tmp_path, rmap: bool = True) -> ServiceConfig:
    cfg = load_config(CONFIG / "default.yaml")
    data = cfg.model_dump()
    data["accelerometer"] = {"enabled": True, "timeout_ms": 20.0}
    if rmap:
        import yaml

        regs = yaml.safe_load((CONFIG / "registers.yaml").read_text())
        regs["from_plc"]["registers"] += [
            {"name": "acc_x", "address": 0x800F, "type": "float32"}, {"name": "acc_y", "address": 0x8011, "type": "float32"},
            {"name": "acc_z", "address": 0x8013, "type": "float32"}, {"name": "acc_samples", "address": 0x8015, "type": "uint16"}]
        (tmp_path / "registers.yaml").write_text(yaml.safe_dump(regs))
        data["plc"]["register_map"] = str(tmp_path / "registers.yaml")
    out = ServiceConfig.model_validate(data)
    out.path = cfg.path
    return out


@pytest.mark.parametrize("compiled", [False, True])
def test_the_cycle_publishes_the_acceleration_and_the_correction_does_not_depend_on_it(tmp_path, compiled):
    model = model_with()
    cycles = {"with": Cycle.from_config(config_with_accelerometer(tmp_path), model),
              "without": Cycle.from_config(load_config(CONFIG / "default.yaml"), model)}
    seen = {}
    for name, c in cycles.items():
        if compiled:
            c.compensator.compile()
        rows = []
        for k in range(1, 400):
            count = min(200, k)                    # the box freezes at 200 ms
            f = [0.1 * np.sin(k / 10.0), 0.0, 9.81]
            c.step(0.001 * k, Reading(W, 0, k, False), [], int(Command.ENABLE) | (int(Command.TARE) if k == 5 else 0),
                   k, Q, inputs=record(f, count))
            s = c.signals()
            rows.append((s.status_word, s.acc_x, s.acc_y, s.acc_z, *c.correction))
        seen[name] = np.array(rows)
    got, ref = seen["with"], seen["without"]
    assert np.array_equal(got[:, 4:], ref[:, 4:])            # the correction: the force alone, either way
    ok = (got[:, 0].astype(int) & int(Status.ACCELEROMETER_OK)) != 0
    assert ok[10:199].all() and not ok[225:].any() and not (ref[:, 0].astype(int) & int(Status.ACCELEROMETER_OK)).any()
    moving = np.linalg.norm(got[10:199, 1:4], axis=1)
    assert moving.max() > 0.05 and np.all(got[225:, 1:4] == 0.0) and np.all(ref[:, 1:4] == 0.0)


def test_an_accelerometer_whose_values_the_map_lacks_refuses_to_start(tmp_path):
    cfg = config_with_accelerometer(tmp_path, rmap=False)
    cfg.plc.role, cfg.ads.enabled, cfg.monitoring.enabled = "none", False, False
    with pytest.raises(ServiceConfigError, match=r"accelerometer.enabled reads acc_x.*no register acc_x, acc_y, acc_z, "
                                                 "acc_samples"):
        Service(cfg)


def write_replay(path, t_s, values) -> None:
    rows = "".join(f"{t:.6f},{float(x)!r},{float(y)!r},{float(z)!r}\n" for t, (x, y, z) in zip(t_s, values))
    path.write_text("# the box's samples, as the PLC passed them\nt_s,acc_x,acc_y,acc_z\n" + rows)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(gaps=st.lists(st.integers(1, 4), min_size=3, max_size=60), values=st.lists(vectors, min_size=60, max_size=60),
       pose=angles)
def test_a_replayed_box_gives_what_the_plcs_samples_gave(tmp_path, gaps, values, pose):
    """The PLC's samples arriving every 1 to 4 cycles, recorded with the cycle time each arrived at, then
    replayed from the file: the acceleration, ok and condition the same at every cycle, the tare's included."""
    R_s = Rotation.from_euler("xyz", pose, degrees=True).as_matrix()
    arrive = np.cumsum([0, *gaps])                            # the cycles at which a new sample came
    f = [box(R_s, np.array(v), np.array([0.05, -0.02, 0.01])) for v in values[:len(arrive)]]
    write_replay(tmp_path / "box.csv", 0.001 * arrive, f)
    live = Accelerometer(AccelerometerConfig(enabled=True, timeout_ms=3.0), G)
    again = Accelerometer(AccelerometerConfig(enabled=True, timeout_ms=3.0, replay=str(tmp_path / "box.csv")), G)
    count = -1
    for k in range(int(arrive[-1]) + 10):                     # and past the file's end
        if k in arrive:
            count += 1
        live.update(0.001 * k, record(f[count], count), R_s, k == 2)
        again.update(0.001 * k, None, R_s, k == 2)
        assert (again.ok, again.condition) == (live.ok, live.condition), k
        assert np.array_equal(again.acceleration, live.acceleration), k
    assert live.condition == FROZEN


def test_a_replays_end_is_named_with_its_file(tmp_path, caplog):
    write_replay(tmp_path / "box.csv", [0.0, 0.001, 0.002], [[0.0, 0.0, 9.81]] * 3)
    acc = Accelerometer(AccelerometerConfig(enabled=True, timeout_ms=5.0, replay=str(tmp_path / "box.csv")), G)
    caplog.set_level(logging.WARNING, logger="stiffcomp.service")
    for k in range(20):
        acc.update(0.001 * k, None, np.eye(3), False)
    assert acc.condition == FROZEN
    named = [r.getMessage() for r in caplog.records if FROZEN in r.getMessage()]
    assert len(named) == 1 and f"no new sample of {tmp_path / 'box.csv'} (its last at 0.002 s)" in named[0]


def test_a_bad_replay_file_is_named_by_line(tmp_path):
    """... and a replay given to an accelerometer that is off is refused, not ignored."""
    with pytest.raises(ValueError, match=r"replay = 'box.csv' is read only with enabled: true"):
        AccelerometerConfig(enabled=False, replay="box.csv")
    path = tmp_path / "box.csv"
    path.write_text("t_s,acc_x,acc_y,acc_z\n0.000,0,0,9.81\n0.001,0,0,9.81\n0.001,0,0,9.81\n")
    with pytest.raises(DataError, match=r"box.csv: line 4: t_s = 0.001 does not increase"):
        BoxReplay(path)
    path.write_text("t_s,acc_x,acc_z\n0.000,0,9.81\n0.001,0,9.81\n")
    with pytest.raises(DataError, match=r"line 1: missing column\(s\) acc_y"):
        BoxReplay(path)
    path.write_text("t_s,acc_x,acc_y,acc_z\n0.000,0,0,9.81\n0.001,0,0,9.8")
    with pytest.raises(DataError, match=r"box.csv"):
        BoxReplay(path)                                        # its last line cut off


def test_a_replayed_box_runs_through_the_cycle_without_the_maps_registers(tmp_path):
    """A config with ``accelerometer.replay`` and the shipped map (no acc registers) starts; the cycle publishes
    the replayed acceleration on both paths alike, and a replay file not there is named by its key."""
    t = 0.001 * np.arange(150)
    write_replay(tmp_path / "box.csv", t, [[0.2 * np.sin(40.0 * x), 0.0, 9.81] for x in t])
    cfg = load_config(CONFIG / "default.yaml")
    data = cfg.model_dump()
    data["accelerometer"] = {"enabled": True, "timeout_ms": 20.0, "replay": str(tmp_path / "box.csv")}
    (tmp_path / "service.yaml").write_text(__import__("yaml").safe_dump(data))
    cfg = load_config(tmp_path / "service.yaml")
    seen = []
    for compiled in (False, True):
        c = Cycle.from_config(cfg, model_with())
        check_plc_values(cfg, c, cfg.register_map())
        if compiled:
            c.compensator.compile()
        rows = []
        for k in range(1, 200):
            c.step(0.001 * k, Reading(W, 0, k, False), [], int(Command.ENABLE) | (int(Command.TARE) if k == 5 else 0),
                   k, Q)
            s = c.signals()
            rows.append((s.status_word, s.acc_x, s.acc_y, s.acc_z))
        seen.append(np.array(rows))
    assert np.allclose(seen[0], seen[1], atol=1e-9)
    ok = (seen[0][:, 0].astype(int) & int(Status.ACCELEROMETER_OK)) != 0
    assert ok[5:140].all() and not ok[175:].any()              # the file ends at 150 ms: frozen 20 ms later
    assert np.abs(seen[0][5:140, 1:4]).max() > 0.1 and np.all(seen[0][175:, 1:4] == 0.0)
    data["accelerometer"]["replay"] = str(tmp_path / "nowhere.csv")
    (tmp_path / "service.yaml").write_text(__import__("yaml").safe_dump(data))
    with pytest.raises(ServiceConfigError, match=r"accelerometer.replay = .*nowhere.csv"):
        load_config(tmp_path / "service.yaml")


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(gaps=st.lists(st.integers(1, 4), min_size=3, max_size=30), values=st.lists(vectors, min_size=30, max_size=30),
       suffix=st.sampled_from([".csv", ".parquet"]))
def test_a_traced_cut_replays_its_box_at_the_same_cycles(tmp_path, gaps, values, suffix):
    """The service records the box in its trace: a cut whose PLC passes samples every 1 to 4 cycles (float32,
    as its registers carry them), traced through the ring to a file, runs again with ``accelerometer.replay``
    naming that trace: every cycle's acceleration, status, reading and count the same, the tare's included."""
    from service.trace import TraceRing
    from stiffness.data.trace_file import TraceFile

    arrive = np.cumsum([2, *gaps])                             # the cycles at which a new sample came
    f = np.float32([box(np.eye(3), np.array(v), np.array([0.05, -0.02, 0.01])) for v in values[:len(arrive)]])
    cfg = config_with_accelerometer(tmp_path)
    live, ring = Cycle.from_config(cfg, model_with()), TraceRing(rows=256)
    seen, count = [], 0
    try:
        for k in range(1, int(arrive[-1]) + 30):               # and past the last sample: frozen
            if k in arrive:
                count += 1
            live.step(0.001 * k, Reading(W, 0, k, False), [], int(Command.ENABLE) | (int(Command.TARE) if k == 5 else 0),
                      k, Q, inputs=record([float(v) for v in f[count - 1]] if count else [0.0, 0.0, 9.81], count))
            seen.append(live.signals())
            ring.put_cycle(0.001 * k, Q, seen[-1], 1)
        with TraceFile(tmp_path / f"trace{suffix}") as out:
            out.write(ring.take())
    finally:
        ring.close()
    cfg.accelerometer = AccelerometerConfig(enabled=True, timeout_ms=20.0, replay=str(tmp_path / f"trace{suffix}"))
    again = Cycle.from_config(cfg, model_with())
    for k, was in enumerate(seen, start=1):
        again.step(0.001 * k, Reading(W, 0, k, False), [], int(Command.ENABLE) | (int(Command.TARE) if k == 5 else 0),
                   k, Q)
        s = again.signals()
        assert (s.status_word, s.acc_x, s.acc_y, s.acc_z) == (was.status_word, was.acc_x, was.acc_y, was.acc_z), k
        assert (s.box_x, s.box_y, s.box_z, s.box_samples) == (was.box_x, was.box_y, was.box_z, was.box_samples), k
    assert seen[-1].box_samples == len(arrive) and not seen[-1].status_word & int(Status.ACCELEROMETER_OK)


def test_a_trace_without_the_boxs_readings_is_refused_by_name(tmp_path):
    from stiffness.data.trace_file import COLUMNS, TraceFile

    rows = np.zeros((50, len(COLUMNS)))
    rows[:, 0], rows[:, 2] = 0.001 * np.arange(50), np.arange(1, 51)
    with TraceFile(tmp_path / "trace.csv") as out:
        out.write(rows)
    with pytest.raises(DataError, match=r"trace.csv: the accelerometer took no reading in this trace"):
        BoxReplay(tmp_path / "trace.csv")
    text = (tmp_path / "trace.csv").read_text().splitlines()
    keep = [k for k, c in enumerate(COLUMNS) if not c.startswith("box_")]
    (tmp_path / "old.csv").write_text("\n".join(",".join(line.split(",")[k] for k in keep) for line in text) + "\n")
    with pytest.raises(DataError, match=r"old.csv: no box_samples column"):
        BoxReplay(tmp_path / "old.csv")
