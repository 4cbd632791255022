"""The robot road's decisions, packet by packet, on a process image (no sockets: `RobotRoad.received`), and the
answers read back by the virtual robot's controller as a robot applies them."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hil.testing import CONFIG
from hil.virtual_robot import controller_for
from plc_link.contract import Command, Fault
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from robot_road import egm, rsi
from robot_road.interface import ZERO6, interface_for
from robot_road.road import RoadSettings, RobotRoad
from robot_road.settings import RobotSettings
from robot_road.tcp import TcpJacobian
from testlib.road import ROBOT, ROBOT_AT, Clock, Q, new_image, publish


@pytest.fixture
def image():
    im = new_image()
    yield im
    im.close()


def road_on(image, clock=None, **robot) -> RobotRoad:
    section = RobotSettings.model_validate({"interface": "kuka_rsi", **robot})
    limits = [(float(lo), float(hi)) for lo, hi in ROBOT.limits_deg]
    return RobotRoad(image, RoadSettings(section, enable_on_start=True, silence_s=0.1, ramp_s=0.2, limits_deg=limits,
                                         robot_file=str(ROBOT.source)), clock=clock or Clock())



def q_of(image) -> list[float]:
    i = image.inputs()
    return [i.q1, i.q2, i.q3, i.q4, i.q5, i.q6]


def test_a_packet_from_another_address_changes_nothing(image):
    road = road_on(image, peer="127.0.0.1")
    before = image.inputs()
    assert road.received(rsi.robot_packet(1000, Q, Q), ("127.0.0.2", 40000)) is None
    assert image.inputs() == before and road.counts.dropped == {"peer": 1}
    assert road.received(rsi.robot_packet(1000, Q, Q), ("::ffff:127.0.0.1", 40000)) is not None    # IPv4-mapped


@pytest.mark.parametrize("data, reason", [
    (rsi.robot_packet(1004, [math.nan, *Q[1:]], Q), "joints"),
    (rsi.robot_packet(1004, [0.0, -60.0, 90.0, 0.0, 60.0, 1e6], Q), "joints"),        # beyond A6's limits
    (rsi.robot_packet(1000, Q, Q), "repeated"),                                        # the same IPOC again
    (rsi.robot_packet(996, Q, Q), "stamp"),                                            # a packet out of order
    (b"<Rob TYPE='KUKA'><IPOC>1004</IPOC>", "malformed"),
    (b'<!DOCTYPE r [<!ENTITY a "aaaa">]><Rob>&a;</Rob>', "malformed"),
])
def test_a_bad_packet_is_counted_and_dropped_unanswered(image, data, reason):
    road = road_on(image)
    assert road.received(rsi.robot_packet(1000, Q, Q), ROBOT_AT) is not None
    before = image.inputs()
    assert road.received(data, ROBOT_AT) is None
    assert image.inputs() == before and road.counts.dropped == {reason: 1}


def test_commands_and_heartbeat_without_a_plc_and_a_new_session_after_silence(image):
    clock = Clock()
    road = road_on(image, clock)
    publish(image, [0.5] * 6)
    first = rsi.read_answer(road.received(rsi.robot_packet(1000, Q, Q), ROBOT_AT))
    i = image.inputs()
    assert first[2] == (0.0,) * 6                                   # a session begins from zero correction
    assert i.command_word == int(Command.ENABLE | Command.RESET) and i.plc_heartbeat == 1
    clock.t += 0.1                                                  # half the ramp, within the silence
    half = rsi.read_answer(road.received(rsi.robot_packet(1004, Q, Q), ROBOT_AT))
    assert half[2] == pytest.approx((0.25,) * 6)
    assert image.inputs().command_word == int(Command.ENABLE) and image.inputs().plc_heartbeat == 2
    for ipoc in (1008, 1012):                                       # within the silence, past the ramp
        clock.t += 0.075
        got = rsi.read_answer(road.received(rsi.robot_packet(ipoc, [q + 0.5 for q in Q], Q), ROBOT_AT))
    assert got[2] == (0.5,) * 6
    road.received(rsi.robot_packet(1016, Q, [q + 0.5 for q in Q]), ROBOT_AT)
    # the commanded joints, as a PLC reports them: the programmed (ASPos) plus the correction the robot holds
    assert q_of(image) == pytest.approx([q + 0.5 for q in Q], abs=1e-5)
    clock.t += 0.15                                                 # silent beyond faults.plc_heartbeat_timeout_ms
    publish(image, [0.5] * 6, fault_word=int(Fault.PLC_HEARTBEAT))
    again = rsi.read_answer(road.received(rsi.robot_packet(1500, Q, Q), ROBOT_AT))
    assert again[2] == (0.0,) * 6 and road.sessions.count == 2
    assert image.inputs().command_word & Command.RESET              # the latched fault is reset by the return
    clock.t += 0.01
    road.received(rsi.robot_packet(1504, Q, Q), ROBOT_AT)
    assert image.inputs().command_word & Command.RESET              # held while a fault remains


def test_the_robots_return_resets_only_the_fault_its_silence_latched(image, caplog):
    """Without a PLC nobody acknowledges a fault: the robot's first contact resets what latched before it (as a
    PLC's start-up does); its return after a silence clears only its own silence's fault, and any other latched
    fault stays, with one warning that says how to reset it."""
    clock = Clock()
    road = road_on(image, clock)
    publish(image, [0.0] * 6, fault_word=int(Fault.SENSOR_TIMEOUT))       # the sensor came up late
    road.received(rsi.robot_packet(1000, Q, Q), ROBOT_AT)
    assert image.inputs().command_word == int(Command.ENABLE | Command.RESET)
    clock.t += 0.5                                                          # silent, then back
    publish(image, [0.0] * 6, fault_word=int(Fault.PLC_HEARTBEAT))
    road.received(rsi.robot_packet(1500, Q, Q), ROBOT_AT)
    assert image.inputs().command_word == int(Command.ENABLE | Command.RESET)
    clock.t += 0.5
    publish(image, [0.0] * 6, fault_word=int(Fault.PLC_HEARTBEAT | Fault.SENSOR_SATURATED))
    road.received(rsi.robot_packet(2000, Q, Q), ROBOT_AT)
    clock.t += 0.004
    road.received(rsi.robot_packet(2004, Q, Q), ROBOT_AT)
    assert image.inputs().command_word == int(Command.ENABLE)
    assert sum("faults beyond its silence" in r.message for r in caplog.records) == 1


def test_the_robots_own_command_word_is_obeyed_whatever_enable_on_start_says(image):
    """With a command element the robot's enable bit alone switches the correction (its 0 is a 0), and the road
    says once at start that plc.enable_on_start is ignored."""
    road = road_on(image, kuka_rsi={"command_element": "StiffCmd"})
    assert road.settings.enable_on_start
    assert any("plc.enable_on_start: true is ignored" in w and "<StiffCmd>" in w for w in road.settings.warnings())
    publish(image, [0.0] * 6, fault_word=int(Fault.PLC_HEARTBEAT))
    road.received(rsi.robot_packet(1000, Q, Q, extra={"StiffCmd": 0}), ROBOT_AT)
    assert image.inputs().command_word == 0            # no enable, and no reset the robot did not ask for
    road.received(rsi.robot_packet(1004, Q, Q, extra={"StiffCmd": 5}), ROBOT_AT)
    assert image.inputs().command_word == int(Command.ENABLE | Command.RESET)


def test_the_robots_own_command_heartbeat_and_payload_elements(image):
    road = road_on(image, kuka_rsi={"command_element": "Cmd", "heartbeat_element": "Hb", "payload_element": "Pay"})
    road.received(rsi.robot_packet(1000, Q, Q, extra={"Cmd": 4, "Hb": 17, "Pay": 2}), ROBOT_AT)
    i = image.inputs()
    assert (i.command_word, i.plc_heartbeat, i.payload_index) == (int(Command.RESET), 17, 2)


def test_with_a_plc_beside_the_road_writes_the_joints_only(image):
    road = road_on(image)
    road.settings.owns_commands = False
    image.write_values({"command_word": 0, "plc_heartbeat": 9})
    road.received(rsi.robot_packet(1000, [q + 1 for q in Q], Q), ROBOT_AT)
    i = image.inputs()
    assert (i.command_word, i.plc_heartbeat) == (0, 9) and q_of(image) == pytest.approx([q + 1 for q in Q])


corrections = st.lists(st.floats(-0.3, 0.3), min_size=6, max_size=6)
joints = st.lists(st.floats(-20.0, 20.0), min_size=6, max_size=6).map(lambda d: list(np.add(Q, d)))


@pytest.mark.parametrize("section", [
    {"interface": "kuka_rsi"},
    {"interface": "kuka_rsi", "kuka_rsi": {"correction": "relative"}},
    {"interface": "kuka_rsi", "kuka_rsi": {"cartesian": True}},
    {"interface": "kuka_rsi", "kuka_rsi": {"cartesian": True, "correction": "relative"}},
    {"interface": "abb_egm", "abb_egm": {"mode": "joint"}},
    {"interface": "abb_egm", "abb_egm": {"mode": "path"}},
], ids=["rsi_ak", "rsi_ak_relative", "rsi_rkorr", "rsi_rkorr_relative", "egm_joint", "egm_path"])
@settings(max_examples=25, deadline=None)
@given(steps=st.lists(st.tuples(joints, corrections), min_size=1, max_size=4))
def test_the_robot_holds_the_correction_the_road_answers(section, steps):
    """Answer after answer, what the controller holds is the joint correction behind the answer: exactly for
    the joint answers, as the same TCP motion for RKorr, and across the path for an EGM path correction."""
    settings_ = RobotSettings.model_validate(section)
    iface, robot = interface_for(settings_, str(ROBOT.source)), controller_for(settings_, ROBOT)
    jac = TcpJacobian(ROBOT)
    joint_mode = settings_.interface == "abb_egm" and settings_.abb_egm.mode == "joint"
    for k, (q, dq) in enumerate(steps):
        t = 0.004 * k
        p = iface.parse(robot.packet(t, q))
        q_prog = iface.programmed(p, iface.held, k == 0)
        # joint mode holds the session's first pose, whatever the robot's planned joints say afterwards
        assert q_prog == pytest.approx(steps[0][0] if joint_mode else q, abs=2e-6)
        assert robot.take(iface.answer(p, q_prog, dq, 0.0), t, q_prog)
        held = robot.holds(t, q_prog)
        assert iface.held == pytest.approx(dq, abs=1e-12)
        if settings_.interface == "kuka_rsi" and not settings_.kuka_rsi.cartesian:
            assert held == pytest.approx(dq, abs=3e-6)             # AK has six decimals
        elif joint_mode:
            assert held == pytest.approx(dq, abs=1e-9)
        elif settings_.interface == "kuka_rsi":
            assert jac.motion(q, held) == pytest.approx(jac.motion(q, dq), abs=2e-5)
        else:
            along = egm.to_path(robot.frame, jac.motion(q, held)[:3])
            wanted = egm.to_path(robot.frame, jac.motion(q, dq)[:3])
            assert along[1:] == pytest.approx(wanted[1:], abs=1e-7) and abs(along[0]) <= 1e-7


def test_a_refused_packet_after_a_silence_begins_no_session(image):
    clock = Clock()
    road = road_on(image, clock)
    road.received(rsi.robot_packet(1000, Q, Q), ROBOT_AT)
    clock.t += 0.5
    assert road.received(rsi.robot_packet(1500, [math.nan, *Q[1:]], Q), ROBOT_AT) is None
    assert road.sessions.count == 1
    publish(image, [0.5] * 6)
    assert rsi.read_answer(road.received(rsi.robot_packet(1504, Q, Q), ROBOT_AT))[2] == (0.0,) * 6
    assert road.sessions.count == 2 and q_of(image) == pytest.approx(Q, abs=1e-5)
    assert ZERO6 == road.iface.history[0][0]


@pytest.mark.parametrize("correction", ["absolute", "relative"])
@settings(max_examples=30, deadline=None)
@given(steps=st.lists(st.tuples(joints, corrections, st.booleans()), min_size=2, max_size=8))
def test_answers_the_robot_missed_are_taken_off_as_its_delay_says(correction, steps):
    """A robot that did not take an answer (late) reports it in ``Delay``; the road then knows it holds what it
    held before (the commanded joints it writes), and a relative answer makes up the increment it missed."""
    section = RobotSettings.model_validate({"interface": "kuka_rsi", "kuka_rsi": {"correction": correction,
                                                                                 "joints": "AIPos"}})
    im = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    clock = Clock()
    road = RobotRoad(im, RoadSettings(section, silence_s=10.0, ramp_s=0.0), clock=clock)
    robot = controller_for(section, ROBOT)
    try:
        for k, (q, dq, taken) in enumerate(steps):
            t = 0.004 * k
            clock.t += 0.004
            robot.actual = None                                # AIPos as commanded, no servo lag
            publish(im, dq)
            held = robot.holds(t, q)
            answer = road.received(robot.packet(t, q), ROBOT_AT)
            # the road took off AIPos what the robot holds (AIPos holds it): the programmed joints, to which the
            # commanded ones add the correction the robot takes with this answer
            assert road.iface.history[-2][0] == pytest.approx(held, abs=3e-6)
            assert q_of(im) == pytest.approx(np.add(q, np.float32(dq)), abs=1e-4)
            if taken:
                assert robot.take(answer, t, q) and robot.holds(t, q) == pytest.approx(dq, abs=3e-6)
            else:
                robot.late += 1                                # as the controller counts an answer not in time
    finally:
        im.close()


def test_a_robot_port_in_use_is_refused_naming_the_key_and_the_udp_listing(image):
    import socket

    from io_base.errors import PlcError
    from io_process.server import IoSettings, IoThread
    from plc_link.settings import PlcSettings

    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        road = RoadSettings(RobotSettings(interface="kuka_rsi", port=port))
        io = IoThread(image, IoSettings(plc=PlcSettings(role="none"), robot=road))
        with pytest.raises(PlcError) as e:
            io.start()
        io.stop()
    assert f"cannot listen for the robot on 127.0.0.1:{port}" in str(e.value)
    assert "robot.port" in str(e.value) and "ss -lunp" in str(e.value), str(e.value)
