"""The virtual devices on their own (fast, no processes): the milling force, the circle's references,
the robot stub, the PLC's program and the virtual sensor on python-can's virtual bus."""

from __future__ import annotations

import time

import can
import numpy as np
import pytest

from hil.robot_stub import RobotStub
from hil.sensor import HilSensor
from hil.testing import truth_with
from hil.world import World
from service.ati import AtiProtocol
from service.config import load_config
from service.errors import CanFrameError, SensorTimeout
from service.sources.can_source import CanSource
from stiffness.model.stiffness_model import StiffnessModel
from testlib.hil import EXAMPLES, scenario

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
    t = np.array([0.5, 1.5, 3.0])
    q = np.array([world.path.q_ref_deg(x) for x in t])
    nominal = TRUTH.robot.frames(np.radians(q))[:, 7, :3, 3]
    np.testing.assert_allclose(stub.tcp(q, np.zeros((3, 3)), t), nominal, atol=1e-12)
    f = np.array([[300.0, -200.0, 150.0]] * 3)
    d1, d2 = stub.tcp(q, f, t) - nominal, stub.tcp(q, 2 * f, t) - nominal
    assert np.linalg.norm(d1, axis=1).min() > 1e-4
    np.testing.assert_allclose(d2, 2 * d1, rtol=1e-3)
    with pytest.raises(ValueError, match="strictly increasing"):
        stub.tcp(q, f, t[::-1])


def test_stub_sees_the_pass_as_one_load_history(world):
    """At the same joints and the same force the arm stands apart between loading and unloading by the
    truth's hysteresis: twice the offset h at joint 2 (the Dahl state near +-1 after 150 Nm of travel,
    its transition being 40 Nm) times the TCP's lever about that joint; a truth without hysteresis does not."""
    h_deg = -0.008
    hysteretic = truth_with([{"effect": "hysteresis", "joint": 2, "offset_deg": h_deg, "transition_Nm": 40}])
    n = 201
    t = np.arange(n) * 0.004
    q = np.tile(world.path.q_ref_deg(0.0), (n, 1))
    up_down = 1.0 - np.abs(np.linspace(-1.0, 1.0, n))                    # 0 -> 1 -> 0
    f = up_down[:, None] * [0.0, 0.0, 400.0]                             # 0 -> 400 N -> 0, up
    rise, fall = n // 4, n - 1 - n // 4                                  # the same force, 200 N
    np.testing.assert_allclose(f[rise], f[fall])
    plain = RobotStub(TRUTH).tcp(q, f, t)
    np.testing.assert_allclose(plain[rise], plain[fall], atol=1e-12)
    p = RobotStub(hysteretic).tcp(q, f, t)
    F = TRUTH.robot.frames(np.radians(q[:1]))[0]
    axis, lever = F[1, :3, 2], F[7, :3, 3] - F[1, :3, 3]                # joint 2 turns about DH frame 1's z
    shift = np.linalg.norm(np.cross(axis, lever)) * np.radians(abs(h_deg))
    gap = np.linalg.norm(p[rise] - p[fall])
    assert 1.9 * shift < gap < 2.0 * shift * (1 + 1e-3), (gap, shift)


def test_misaligned_sensor_reports_the_true_wrench_turned_and_the_arm_deflects_under_the_true_one(world):
    """The model's convention W_true = L W_measured (L = StiffnessModel.input_map) on both devices:
    the sensor turned by 3 deg about its z reports L^-1 of the aligned sensor's wrench (bias apart),
    and the stub of the misaligned truth deflects as the aligned truth's under the same true force."""
    turned = truth_with([{"effect": "sensor_misalignment", "rz_deg": 3.0}])
    L = turned.input_map()
    sc = scenario()
    seen = World(sc, TRUTH.robot, load_config(sc.resolve(sc.service)).gravity, L)
    t = np.linspace(0.5, world.path.duration - 0.5, 41)                   # in the cut: a horizontal force
    bias = world.gravity.bias
    aligned, reported = world.sensor_wrench(t) - bias, seen.sensor_wrench(t) - bias
    np.testing.assert_allclose(reported @ L.T, aligned, atol=1e-9)
    for a, r in ((aligned[:, :3], reported[:, :3]), (aligned[:, 3:], reported[:, 3:])):
        np.testing.assert_allclose(np.linalg.norm(r, axis=1), np.linalg.norm(a, axis=1), rtol=1e-12)
        turn = np.degrees(np.arctan2(np.cross(r, a)[:, 2], np.sum(r[:, :2] * a[:, :2], axis=1)))
        np.testing.assert_allclose(turn, 3.0, atol=1e-9)                   # turned back by +3 deg about z
        np.testing.assert_allclose(r[:, 2], a[:, 2], atol=1e-9)
    q = np.array([world.path.q_ref_deg(x) for x in t])
    f = world.force(t)
    np.testing.assert_allclose(RobotStub(turned).tcp(q, f, t), RobotStub(TRUTH).tcp(q, f, t), atol=1e-12)


def test_structure_passes_a_steady_load_and_not_the_tooth_passing():
    stub = RobotStub(TRUTH, 20.0)
    t = np.arange(4000) / 4000.0
    steady = stub.structural_load(t, np.tile([100.0, -50.0, 20.0], (len(t), 1)))
    np.testing.assert_allclose(steady[-1], [100.0, -50.0, 20.0], rtol=1e-3)
    tooth = stub.structural_load(t, np.sin(2 * np.pi * 400 * t)[:, None] * [100.0, 0, 0])
    assert np.abs(tooth[2000:, 0]).max() < 0.5


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
