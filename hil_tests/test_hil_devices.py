"""The virtual devices on their own (fast, no processes): the milling force, the circle's references,
the robot stub, the PLC's program and the virtual sensor on python-can's virtual bus."""

from __future__ import annotations

import time

import can
import numpy as np
import pytest
from hil_lib import EXAMPLES, RMAP, scenario

from hil.robot_stub import RobotStub
from hil.sensor import HilSensor
from hil.virtual_plc import PlcFaults, PlcLogic
from hil.world import World
from plc_interface.contract import Command
from service.ati import AtiProtocol
from service.config import load_config
from service.errors import CanFrameError, SensorTimeout
from service.sources.can_source import CanSource
from stiffness.model import StiffnessModel

TRUTH = StiffnessModel.from_yaml(EXAMPLES / "truth_reference.yaml")


@pytest.fixture(scope="module")
def world() -> World:
    sc = scenario()
    return World(sc, TRUTH.robot, load_config(sc.resolve(sc.service)).gravity)


# -- milling force ----------------------------------------------------------------------------------
def test_no_force_before_the_cut_or_after_the_exit(world):
    t = np.concatenate([np.linspace(world.t_start, -1e-6, 50), np.linspace(world.milling.end_s + 1e-6, world.t_end, 50)])
    assert np.abs(world.force(t)).max() == 0.0


def test_force_follows_the_feed_direction(world):
    """Averaged over whole tooth passes in the steady cut: against the feed, towards the centre, up."""
    p, m = world.path, world.milling
    for t_mid in (1.0, 2.0, 3.0, 4.0):
        t = t_mid + np.arange(200) / (200 * m.f_tooth) * 20          # 20 tooth passes
        F = world.force(t).mean(0)
        phi = p.angle(t.mean())
        assert F @ p.tangent(phi) == pytest.approx(-m.Ff, rel=0.05)
        assert F @ p.outward(phi) == pytest.approx(-m.Fn, rel=0.05)
        assert F[2] == pytest.approx(m.Fa, rel=0.05)


def test_tooth_passing_is_the_dominant_oscillation(world):
    fs = 20_000.0
    t = 1.0 + np.arange(int(fs)) / fs
    f = world.force(t)[:, 0]
    spec = np.abs(np.fft.rfft(f - f.mean()))
    assert np.fft.rfftfreq(len(t), 1 / fs)[spec.argmax()] == pytest.approx(world.milling.f_tooth, abs=1.5)


def test_same_seed_same_trace_another_seed_another():
    sc = scenario()
    t = np.linspace(0, 4, 4001)
    a, b = World(sc, TRUTH.robot).force(t), World(sc, TRUTH.robot).force(t)
    np.testing.assert_array_equal(a, b)
    sc.milling.seed += 1
    assert np.abs(World(sc, TRUTH.robot).force(t) - a).max() > 1.0


def test_entry_overshoots_then_settles(world):
    m = world.milling
    e = m.engagement(np.array([m.entry_s, 10 * m.tau + m.entry_s]))
    assert e[0] > 1.0 + 0.5 * m.overshoot * np.exp(-m.entry_s / m.tau) and e[1] == pytest.approx(1.0, abs=1e-3)


# -- path -------------------------------------------------------------------------------------------
def test_references_put_the_unloaded_tcp_on_the_circle(world):
    p = world.path
    t = np.linspace(-0.2, p.duration + 0.2, 997)
    q = np.array([p.q_ref_deg(x) for x in t])
    F = TRUTH.robot.frames(np.radians(q))
    _, err = p.radial_error(F[:, 7, :3, 3])
    assert np.abs(err).max() < 1e-6                                   # m: the chord's sagitta
    assert np.abs(F[:, 7, :3, :3] - p.R_tool).max() < 1e-6           # the tool keeps its orientation
    np.testing.assert_allclose(F[:, 7, 2, 3], p.center[2], atol=1e-9)


# -- robot stub -------------------------------------------------------------------------------------
def test_stub_without_load_is_the_kinematics_and_linear_in_the_load(world):
    stub = RobotStub(TRUTH)
    q = np.array([world.path.q_ref_deg(x) for x in (0.5, 1.5, 3.0)])
    nominal = TRUTH.robot.frames(np.radians(q))[:, 7, :3, 3]
    np.testing.assert_allclose(stub.tcp(q, np.zeros((3, 3))), nominal, atol=1e-12)
    f = np.array([[300.0, -200.0, 150.0]] * 3)
    d1, d2 = stub.tcp(q, f) - nominal, stub.tcp(q, 2 * f) - nominal
    assert np.linalg.norm(d1, axis=1).min() > 1e-4
    np.testing.assert_allclose(d2, 2 * d1, rtol=1e-3)


def test_structure_passes_a_steady_load_and_not_the_tooth_passing():
    stub = RobotStub(TRUTH, 20.0)
    t = np.arange(4000) / 4000.0
    steady = stub.structural_load(t, np.tile([100.0, -50.0, 20.0], (len(t), 1)))
    np.testing.assert_allclose(steady[-1], [100.0, -50.0, 20.0], rtol=1e-3)
    tooth = stub.structural_load(t, np.sin(2 * np.pi * 400 * t)[:, None] * [100.0, 0, 0])
    assert np.abs(tooth[2000:, 0]).max() < 0.5


# -- the PLC's program ------------------------------------------------------------------------------
def plc(**kw) -> PlcLogic:
    return PlcLogic(RMAP, lambda t: [10.0, -60.0, 90.0, 0.0, 60.0, 0.0], service_timeout_s=0.1,
                    max_rate_deg_s=2.0, **kw)


def service_values(hb: int, corr: list[float]) -> list[float]:
    names = RMAP.codecs["to_plc"].names
    v = dict.fromkeys(names, 0.0) | {"heartbeat": hb} | {f"correction_q{i + 1}": c for i, c in enumerate(corr)}
    return [v[n] for n in names]


def step(logic, t, values):
    out, q = logic.step(t, values)
    return dict(zip(RMAP.codecs["from_plc"].names, out)), q


def test_plc_without_the_service_follows_its_references():
    logic = plc()
    for k in range(100):
        out, q = step(logic, k * 0.004, None)
        assert q == logic.reference(k * 0.004) and out["command_word"] == Command.ENABLE
    assert out["plc_heartbeat"] == 100


def test_plc_applies_the_correction_rate_limited_and_drops_it_when_the_link_goes_stale():
    logic, corr, dt = plc(), [0.05, -0.02, 0.01, 0.0, 0.0, 0.0], 0.004
    seen = []
    for k in range(100):
        _, q = step(logic, k * dt, service_values(k, corr))
        seen.append(list(logic.applied))
    steps = np.abs(np.diff(np.array(seen), axis=0))
    assert steps.max() <= 2.0 * dt + 1e-12
    np.testing.assert_allclose(seen[-1], corr)
    np.testing.assert_allclose(np.array(q) - logic.reference(0), corr)
    for k in range(100, 200):                      # the service's heartbeat freezes
        step(logic, k * dt, service_values(99, corr))
    assert logic.applied == [0.0] * 6 and not logic.link_ok


def test_plc_pulses_reset_on_first_contact_and_after_a_loss_only():
    logic, dt = plc(), 0.004
    resets = [step(logic, k * dt, service_values(k, [0.0] * 6) if not 50 <= k < 100 else None)[0]["command_word"]
              & Command.RESET for k in range(200)]
    assert [k for k, r in enumerate(resets) if r] == [0, 100]


def test_plc_uncompensated_neither_enables_nor_applies():
    logic = plc(compensate=False)
    for k in range(50):
        out, q = step(logic, k * 0.004, service_values(k, [0.1] * 6))
    assert out["command_word"] & Command.ENABLE == 0 and q == logic.reference(0)


def test_plc_heartbeat_freezes_when_told():
    logic = plc(faults=PlcFaults(heartbeat_stop_at=0.1))
    hb = [step(logic, k * 0.004, None)[0]["plc_heartbeat"] for k in range(60)]
    assert len(set(hb[25:])) == 1 and len(set(hb[:25])) == 25


# -- the virtual sensor, within one process ---------------------------------------------------------
@pytest.mark.parametrize("fault", [None, ("stop", 0.0), ("babble", 0.0)])
def test_sensor_on_a_virtual_bus(world, fault):
    """Before the cut it reports the payload and bias exactly (to the protocol's counts); a stopped
    sensor times out, a babbling one gives CAN frame errors."""
    channel = f"hil-{fault}"
    go = (lambda: time.monotonic() - 1.0) if fault else (lambda: None)
    sensor = HilSensor(can.Bus(interface="virtual", channel=channel), AtiProtocol(), world, go, [0.0] * 6,
                       fault=fault)
    src = CanSource(can.Bus(interface="virtual", channel=channel), protocol=AtiProtocol(), timeout_s=0.05,
                    max_force_N=2500.0, max_torque_Nm=250.0)
    readings, errors = [], []
    with sensor:
        try:
            for k in range(300):
                r, e = src.poll(k * 1e-3)
                errors += e
                if r is not None:
                    readings.append(r.wrench)
                time.sleep(1e-3)
        finally:
            src.close()
    if fault is None:
        assert len(readings) > 50 and not errors
        expected = world.sensor_wrench(np.array([world.t_start]))[0]
        np.testing.assert_allclose(np.array(readings), np.tile(expected, (len(readings), 1)), atol=0.051)
    elif fault[0] == "stop":
        assert not readings and any(isinstance(e, SensorTimeout) for e in errors)
    else:
        assert any(isinstance(e, CanFrameError) for e in errors)
