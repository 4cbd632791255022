"""The robot road's meaning of each interface, packet by packet against the virtual controllers that follow the
makers' definitions (no sockets, a clock of the test's own): EGM joint mode holds its pose against a robot whose
``planned`` is its reference, a robot that restarts its interface is answered at once, a robot on another cycle
is named, KUKA's joints are checked against the packets, and what cannot be answered is refused by name."""

from __future__ import annotations

import logging

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.testing import CONFIG
from hil.virtual_robot import controller_for
from plc_link.contract import to_plc
from robot_road import egm, rsi
from robot_road.kuka_rsi import CHECK_PACKETS
from robot_road.road import RoadSettings, RobotRoad
from robot_road.settings import RobotSettings
from robot_road.tcp import motion_of_rkorr, rkorr
from testlib.road import LIMITS, ROBOT, ROBOT_AT, Clock, Q, new_image, publish

Q = np.array(Q)


@pytest.fixture
def image():
    im = new_image()
    yield im
    im.close()


def road_on(image, clock, section: dict, ramp_s: float = 0.0) -> RobotRoad:
    s = RobotSettings.model_validate(section)
    return RobotRoad(image, RoadSettings(s, enable_on_start=True, silence_s=0.2, ramp_s=ramp_s, limits_deg=LIMITS,
                                         robot_file=str(ROBOT.source)), clock=clock)


def hold(image, seconds: float, old_answer: bool = False) -> np.ndarray:
    """EGM joint mode for ``seconds`` against the virtual ABB controller (``planned`` its reference, moved toward
    each target through EGM's filter), the correction between 0.01 and 0.05 deg: per cycle the target's and the
    reference's largest distance from the programmed pose. ``old_answer``: the road answers planned + correction,
    as it once did."""
    clock = Clock()
    section = {"interface": "abb_egm", "abb_egm": {"mode": "joint"}}
    road = road_on(image, clock, section)
    if old_answer:
        road.iface.programmed = lambda p, held, new: list(p.joints_deg)
    robot = controller_for(RobotSettings.model_validate(section), ROBOT)
    far = []
    for k in range(int(seconds / robot.period)):
        t = k * robot.period
        clock.t += robot.period
        publish(image, 0.03 + 0.02 * np.sin(np.array([1.0, 1.3, 0.7, 2.1, 1.7, 0.9]) * t + np.arange(6)))
        answer = road.received(robot.packet(t, Q), ROBOT_AT)
        assert answer is not None and robot.take(answer, t, Q)
        far.append((np.abs(np.subtract(robot.answer, Q)).max(), np.abs(robot.commanded(t, Q) - Q).max()))
    return np.array(far)


def test_egm_joint_mode_holds_its_pose_where_the_old_answer_ratchets(image):
    """ABB's manual: ``planned`` is the robot's reference, the target it moves to. An answer of planned + dq is
    added again every cycle: the old answer ran away; the pose of the session's start + dq stays within the
    correction's size of the programmed pose for 60 s."""
    target, reference = hold(image, 60.0).T
    assert target.max() <= 0.05 + 1e-6, target.max()
    assert reference.max() <= 1.05 * 0.05, reference.max()      # EGM's filter overshoots a little
    target, reference = hold(image, 5.0, old_answer=True).T
    assert reference.max() > 10 * 0.05, reference.max()        # ten times the correction within 5 s, and rising
    assert reference[-1] > reference[len(reference) // 2] and target.max() > 10 * 0.05


@pytest.mark.parametrize("section, fall_back", [
    ({"interface": "kuka_rsi"}, 60_000),
    ({"interface": "abb_egm", "abb_egm": {"mode": "joint"}}, None),
    ({"interface": "abb_egm", "abb_egm": {"mode": "path"}}, None),
], ids=["rsi", "egm_joint", "egm_path"])
def test_a_robot_that_restarts_its_interface_is_answered_within_three_packets(image, caplog, section, fall_back):
    """A new RSI_ON (IPOC falls back) or a new EGM instruction (seqno from 1) without a pause: a new session at
    once, answered from zero and ramping in; a duplicate is still dropped and named for what it is."""
    clock = Clock()
    road = road_on(image, clock, section, ramp_s=0.2)
    robot = controller_for(RobotSettings.model_validate(section), ROBOT)
    publish(image, [0.02] * 6)
    period = robot.period * robot.every
    t = 0.0
    for _ in range(100):
        clock.t += period
        assert robot.take(road.received(robot.packet(t, Q), ROBOT_AT), t, Q)
        t += period
    dup = robot.packet(t, Q)
    clock.t += period
    assert road.received(dup, ROBOT_AT) is not None
    assert road.received(dup, ROBOT_AT) is None and road.counts.dropped == {"repeated": 1}
    robot.restart()
    answered = []
    for _ in range(3):
        clock.t += period
        t += period
        answered.append(road.received(robot.packet(t, Q), ROBOT_AT) is not None)
    assert answered[0] and all(answered), answered
    assert road.sessions.restarts == 1 and road.sessions.count == 2
    assert any("fell back" in r.message for r in caplog.records)
    assert road.iface.held != (0.02,) * 6 or road.settings.ramp_s == 0   # ramping in again from zero


def test_a_robot_on_another_cycle_is_named_and_its_packets_are_not_counted_lost(image, caplog):
    """A 12 ms IPO (#IPO) against cycle_ms 4: one warning naming the key and the robot's cycle; no stamp gaps."""
    clock = Clock()
    road = road_on(image, clock, {"interface": "kuka_rsi", "kuka_rsi": {"cycle_ms": 4}})
    for k in range(60):
        clock.t += 0.012
        assert road.received(rsi.robot_packet(1000 + 12 * k, Q, Q), ROBOT_AT) is not None
    said = [r.message for r in caplog.records if "cycle looks like" in r.message]
    assert len(said) == 1 and "12 ms" in said[0] and "robot.kuka_rsi.cycle_ms" in said[0], said
    assert road.counts.stamp_gaps == 0 and road.stats()["cycle_seen_ms"] == 12


def test_an_egm_path_packet_without_the_planned_pose_is_dropped_by_name(image):
    clock = Clock()
    road = road_on(image, clock, {"interface": "abb_egm", "abb_egm": {"mode": "path"}})
    assert road.received(egm.robot_packet(1, 1000, Q, Q), ROBOT_AT) is None
    assert road.counts.dropped == {"pose": 1} and road.counts.answered == 0


@pytest.mark.parametrize("holds", [False, True], ids=["kr_c4", "aspos_holds"])
def test_kuka_joints_are_checked_against_the_packets(image, caplog, holds):
    """AIPos - ASPos follows the correction the robot holds when ASPos does not hold it (a KR C4), not when it
    does: the setting that contradicts the packets is warned about within 2 s, naming the key and the slope."""
    for setting in (False, True):
        caplog.clear()
        clock = Clock()
        section = {"interface": "kuka_rsi", "kuka_rsi": {"joints_include_correction": setting}}
        road = road_on(image, clock, section)
        robot = controller_for(RobotSettings.model_validate(section), ROBOT, aspos_holds_correction=holds)
        n = int(2.0 / robot.period)
        for k in range(n):
            t = k * robot.period
            clock.t += robot.period
            q_ref = Q + 2.0 * np.sin(0.5 * t)                   # a moving robot: the servo lags
            publish(image, 0.04 * np.sin(np.array([3.0, 2.0, 4.0, 5.0, 3.5, 2.5]) * t))
            robot.take(road.received(robot.packet(t, q_ref), ROBOT_AT), t, q_ref)
            road.after_answer()                                 # as the I/O loop does once the answer is sent
            robot.commanded(t, q_ref)
        check = road.stats()["joints_check"]
        assert check["windows"] >= n // CHECK_PACKETS - 1 and abs(check["slope"] - (0.0 if holds else 1.0)) < 0.2
        warned = [r.message for r in caplog.records if "joints_include_correction" in r.message]
        assert check["agrees"] == (setting == holds)
        assert len(warned) == (0 if setting == holds else 1), warned
        if warned:
            assert f"set joints_include_correction: {str(holds).lower()}" in warned[0]


def test_an_interface_without_its_section_says_it_runs_on_defaults():
    s = RobotSettings.model_validate({"interface": "abb_egm"})
    assert "no robot.abb_egm section" in s.defaults_warning() and "48 ms, path mode" in s.defaults_warning()
    assert RobotSettings.model_validate({"interface": "abb_egm", "abb_egm": {}}).defaults_warning() is None
    assert RobotSettings.model_validate({"interface": "kuka_rsi"}).kuka_rsi.includes_correction is False
    aipos = RobotSettings.model_validate({"interface": "kuka_rsi", "kuka_rsi": {"joints": "AIPos"}})
    assert aipos.kuka_rsi.includes_correction is True


def test_egm_sample_rates_are_the_manuals():
    with pytest.raises(ValueError, match="multiple of 24 ms in path mode"):
        RobotSettings.model_validate({"interface": "abb_egm", "abb_egm": {"mode": "path", "cycle_ms": 4}})
    with pytest.raises(ValueError, match="multiple of 4 ms in joint mode"):
        RobotSettings.model_validate({"interface": "abb_egm", "abb_egm": {"mode": "joint", "cycle_ms": 6}})
    assert RobotSettings.model_validate({"interface": "abb_egm", "abb_egm": {"mode": "joint"}}).cycle_ms == 4


@settings(max_examples=200, deadline=None)
@given(axis=st.lists(st.floats(-1.0, 1.0), min_size=3, max_size=3).filter(lambda v: np.linalg.norm(v) > 1e-3),
       size=st.floats(0.0, 1.0))
def test_rkorr_angles_are_the_rotation_within_the_stated_bound(axis, size):
    """RKorr's A, B, C (ZYX) from a small rotation vector: within 0.0044 deg x (|r| / 1 deg)^2 of the exact ZYX
    angles (tcp.rkorr's docstring), and read back exactly by the robot's side."""
    from scipy.spatial.transform import Rotation

    r = np.asarray(axis) / np.linalg.norm(axis) * size
    motion = (0.1, -0.2, 0.3, *r)
    values = rkorr(motion)
    exact = Rotation.from_rotvec(np.radians(r)).as_euler("ZYX", degrees=True)
    assert np.abs(np.array(values[3:]) - exact).max() <= 0.0044 * size ** 2 + 1e-12
    assert motion_of_rkorr(values) == pytest.approx(motion)


def test_a_failing_answer_is_counted_once_not_logged_per_packet(image, caplog):
    """A packet whose answer cannot be built (here an answer function that raises) is dropped as ``failed``, and
    the log says so at a limited rate, not once per packet."""
    from robot_road.road import _Datagrams

    clock = Clock()
    road = road_on(image, clock, {"interface": "kuka_rsi"})

    def broken(*a):
        raise RuntimeError("broken")

    road.iface.answer = broken
    proto = _Datagrams(road)
    caplog.set_level(logging.INFO)
    for k in range(50):
        clock.t += 0.004
        proto.datagram_received(rsi.robot_packet(1000 + 4 * k, Q, Q), ROBOT_AT)
    assert road.counts.dropped == {"failed": 50} and road.counts.answered == 0
    assert sum("failed" in r.message for r in caplog.records) <= 2


def test_an_egm_path_correction_is_never_younger_than_one_ms(image):
    """ABB's age counts whole milliseconds since the measurement; a public sender never sends less than 1."""
    clock = Clock()
    road = road_on(image, clock, {"interface": "abb_egm", "abb_egm": {"mode": "path"}})
    robot = controller_for(RobotSettings.model_validate({"interface": "abb_egm", "abb_egm": {"mode": "path"}}), ROBOT)
    image.publish(to_plc(sample_age_ms=0.0, correction_q1=0.01))
    _, kind, _, age, _ = egm.read_answer(road.received(robot.packet(0.0, Q), ROBOT_AT))
    assert kind == "path" and age == 1


@pytest.mark.parametrize("section", [{"interface": "kuka_rsi"}, {"interface": "abb_egm", "abb_egm": {"mode": "path"}}],
                         ids=["rsi", "egm_path"])
def test_the_virtual_robot_takes_an_answer_extra_delay_later(section):
    """`hil circle --extra-delay-ms` on the robot road: the robot holds an answer only that much after it came."""
    s = RobotSettings.model_validate(section)
    iface = controller_for(s, ROBOT, delay_s=0.012)
    from robot_road.interface import interface_for

    road = interface_for(s, str(ROBOT.source))
    p = road.parse(iface.packet(0.0, Q))
    assert iface.take(road.answer(p, list(Q), [0.02] * 6, 5.0), 0.0, Q)
    assert np.abs(iface.holds(0.008, Q)).max() == 0.0
    assert np.abs(iface.holds(0.012, Q)).max() > 0.001


def test_without_a_plc_the_heartbeat_fault_and_its_reset_name_the_robot(caplog):
    from service.faults import FaultMonitor
    from service.supervision import Supervisor

    faults = FaultMonitor("the robot (KUKA RSI packets)")
    sup = Supervisor(faults, np.array(LIMITS), 0.1, 10)
    sup.update(0.0, 1, 1, list(Q), False, [])
    sup.update(0.5, 1, 1, list(Q), False, [])
    assert "plc_heartbeat of the robot (KUKA RSI packets) unchanged" in faults.last_message["plc_heartbeat"]
    sup.update(0.6, 1 | 4, 2, list(Q), False, [])
    assert any("faults reset by the robot (KUKA RSI packets)" in r.message for r in caplog.records)


def test_the_config_names_who_commands():
    from service.config import load_config

    assert load_config(CONFIG / "robot_kuka_rsi.yaml").commander == "the robot (KUKA RSI packets)"
    assert load_config(CONFIG / "default.yaml").commander == "the PLC"
    assert not load_config(CONFIG / "robot_kuka_rsi.yaml").cycle_enables_on_start


def test_every_interface_is_declared_once_and_read_from_its_declaration():
    """A robot interface is one declaration (its settings, its road side, its virtual controller), found by its
    name; its sub-section answers what the road asks of every robot."""
    from robot_road import registry
    from robot_road.interface import RobotInterface, interface_for
    from robot_road.registry import RobotSection

    assert set(registry.names()) >= {"kuka_rsi", "abb_egm"}
    for name in registry.names():
        d = registry.declared(name)
        assert d.name == name and isinstance(d.settings(), RobotSection)
        section = {"interface": name, name: {"mode": "joint"}} if name == "abb_egm" else {"interface": name}
        s = RobotSettings.model_validate(section)
        assert type(s.section) is d.settings and getattr(s, name) == s.section
        assert isinstance(interface_for(s), RobotInterface)
        assert controller_for(s, ROBOT).period > 0
