"""ABB EGM packets (robot_road.egm): ABB's field numbers on the wire, the robot's packet read and the
sensor's answers written (round trips), every bad datagram refused with PacketError, the path frame as
ABB defines it, and egm_pb2.py being protoc's code for egm.proto at the protobuf floor pyproject names."""

from __future__ import annotations

import ast
import importlib.util
import math
import struct
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest
from google.protobuf.descriptor import FieldDescriptor as FD
from hypothesis import assume, given, settings
from hypothesis import strategies as st

from robot_road import egm
from robot_road import egm_pb2 as pb
from robot_road.packets import PacketError

ROOT = Path(__file__).resolve().parents[2]
ROBOT = ROOT / "robot_road"

u32 = st.integers(0, 2**32 - 1)
deg = st.floats(-720, 720, allow_nan=False)
six = st.tuples(*[deg] * 6)
mm = st.floats(-5000, 5000, allow_nan=False)


@st.composite
def unit_quaternions(draw) -> tuple[float, float, float, float]:
    q = draw(st.tuples(*[st.floats(-1, 1)] * 4))
    n = math.sqrt(sum(c * c for c in q))
    assume(n > 0.1)
    return tuple(c / n for c in q)


poses = st.builds(lambda p, q: (*p, *q), st.tuples(mm, mm, mm), unit_quaternions())


# -- ABB's layout -------------------------------------------------------------------------------------------
# (message, field, number) as ABB's egm.proto gives them: ros-industrial/abb_libegm proto/egm.proto
# ("ABB sensor interface V1.1") and the EgmRobot/EgmSensor listings of ABB's Application manual Externally
# Guided Motion (3HAC073318-001, RobotWare 7), which agree on every number here
ABB_FIELDS = [
    ("EgmHeader", "seqno", 1), ("EgmHeader", "tm", 2), ("EgmHeader", "mtype", 3),
    ("EgmCartesian", "x", 1), ("EgmCartesian", "y", 2), ("EgmCartesian", "z", 3),
    ("EgmQuaternion", "u0", 1), ("EgmQuaternion", "u1", 2), ("EgmQuaternion", "u2", 3), ("EgmQuaternion", "u3", 4),
    ("EgmPose", "pos", 1), ("EgmPose", "orient", 2), ("EgmPose", "euler", 3), ("EgmJoints", "joints", 1),
    ("EgmPlanned", "joints", 1), ("EgmPlanned", "cartesian", 2), ("EgmPlanned", "externalJoints", 3),
    ("EgmPlanned", "time", 4), ("EgmFeedBack", "joints", 1), ("EgmFeedBack", "cartesian", 2),
    ("EgmPathCorr", "pos", 1), ("EgmPathCorr", "age", 2), ("EgmMotorState", "state", 1),
    ("EgmRobot", "header", 1), ("EgmRobot", "feedBack", 2), ("EgmRobot", "planned", 3),
    ("EgmRobot", "motorState", 4), ("EgmRobot", "mciState", 5), ("EgmRobot", "mciConvergenceMet", 6),
    ("EgmRobot", "testSignals", 7), ("EgmRobot", "rapidExecState", 8), ("EgmRobot", "utilizationRate", 10),
    ("EgmRobot", "moveIndex", 11), ("EgmSensor", "header", 1), ("EgmSensor", "planned", 2),
    ("EgmSensor", "speedRef", 3), ("EgmSensorPathCorr", "header", 1), ("EgmSensorPathCorr", "pathCorr", 2),
]
ABB_ENUMS = {
    pb.EgmHeader.MessageType: {"MSGTYPE_UNDEFINED": 0, "MSGTYPE_COMMAND": 1, "MSGTYPE_DATA": 2,
                               "MSGTYPE_CORRECTION": 3, "MSGTYPE_PATH_CORRECTION": 4},
    pb.EgmMotorState.MotorStateType: {"MOTORS_UNDEFINED": 0, "MOTORS_ON": 1, "MOTORS_OFF": 2},
    pb.EgmMCIState.MCIStateType: {"MCI_UNDEFINED": 0, "MCI_ERROR": 1, "MCI_STOPPED": 2, "MCI_RUNNING": 3},
    pb.EgmRapidCtrlExecState.RapidCtrlExecStateType: {"RAPID_UNDEFINED": 0, "RAPID_STOPPED": 1, "RAPID_RUNNING": 2},
}


@pytest.mark.parametrize(("message", "field", "number"), ABB_FIELDS)
def test_field_numbers_are_abbs(message, field, number):
    assert getattr(pb, message).DESCRIPTOR.fields_by_name[field].number == number


def test_package_types_and_enums_are_abbs():
    assert pb.DESCRIPTOR.package == "abb.egm"
    f = pb.EgmHeader.DESCRIPTOR.fields_by_name
    assert (f["seqno"].type, f["tm"].type) == (FD.TYPE_UINT32, FD.TYPE_UINT32)
    assert pb.EgmJoints.DESCRIPTOR.fields_by_name["joints"].type == FD.TYPE_DOUBLE
    assert pb.EgmPathCorr.DESCRIPTOR.fields_by_name["age"].type == FD.TYPE_UINT32
    assert pb.EgmPathCorr.DESCRIPTOR.fields_by_name["pos"].is_required
    for enum, values in ABB_ENUMS.items():
        assert dict(enum.items()) == values


def _tag(field: int, wire: int) -> bytes:
    return bytes([field << 3 | wire])


def _sub(field: int, body: bytes) -> bytes:
    return _tag(field, 2) + bytes([len(body)]) + body


def _doubles(field: int, values) -> bytes:
    return b"".join(_tag(field, 1) + struct.pack("<d", v) for v in values)


def test_a_datagram_encoded_by_hand_from_abbs_numbers_is_read():
    """Written byte by byte from ABB's numbers, with fields egm.proto leaves out (RobotWare 7's measuredForce
    9 and RAPIDfromRobot 13) that the parser skips."""
    q = (10.5, -20.25, 30.0, 0.0, 45.0, -90.0)
    header = _tag(1, 0) + b"\x2a" + _tag(2, 0) + b"\xe8\x07" + _tag(3, 0) + b"\x02"     # 42, 1000 ms, DATA
    pose = _sub(1, _doubles(1, [1.0]) + _doubles(2, [2.0]) + _doubles(3, [3.0])) + \
        _sub(2, _doubles(1, [1.0]) + _doubles(2, [0.0]) + _doubles(3, [0.0]) + _doubles(4, [0.0]))
    planned = _sub(1, _doubles(1, q)) + _sub(2, pose)
    force = _tag(1, 0) + b"\x01" + _doubles(2, [0.5] * 6)
    data = _sub(1, header) + _sub(2, _sub(1, _doubles(1, [0.0] * 6))) + _sub(3, planned) + _sub(9, force) + \
        _sub(13, _doubles(2, [7.0] * 3))
    p = egm.parse(data)
    assert (p.stamp, p.tm_ms, p.joints_deg, p.pose, p.late) == (42, 1000, q, (1.0, 2.0, 3.0, 1.0, 0.0, 0.0, 0.0),
                                                                None)


# -- round trips --------------------------------------------------------------------------------------------
@given(seqno=u32, tm=u32, planned=six, feedback=six, pose=st.none() | poses)
def test_robot_packet_parses_back(seqno, tm, planned, feedback, pose):
    data = egm.robot_packet(seqno, tm, planned, feedback, pose)
    assert len(data) <= egm.MAX_BYTES
    p = egm.parse(data)
    assert (p.stamp, p.tm_ms, p.joints_deg, p.pose, p.late) == (seqno, tm, planned, pose, None)


@given(seqno=st.integers(0, 2**40), q=six, tm=st.none() | u32)
def test_joint_answer_reads_back(seqno, q, tm):
    data = egm.joint_answer(seqno, q, tm)
    assert egm.read_answer(data) == (seqno % 2**32, "joints", q, None, tm)
    msg = pb.EgmSensor.FromString(data)
    assert msg.header.mtype == pb.EgmHeader.MSGTYPE_CORRECTION
    assert msg.header.HasField("tm") == (tm is not None)


@given(seqno=u32, pos=st.tuples(mm, mm, mm), age=st.integers(-100, 2**33))
def test_path_answer_reads_back(seqno, pos, age):
    data = egm.path_answer(seqno, pos, age)
    assert egm.read_answer(data) == (seqno, "path", pos, min(max(age, 0), 2**32 - 1), None)
    assert pb.EgmSensorPathCorr.FromString(data).header.mtype == pb.EgmHeader.MSGTYPE_PATH_CORRECTION


def test_a_joint_answer_takes_six_finite_joints():
    for q in ((0.0,) * 5, (0.0,) * 7, (0.0, 0.0, math.nan, 0.0, 0.0, 0.0), (math.inf,) * 6):
        with pytest.raises(ValueError, match="six finite joints"):
            egm.joint_answer(1, q)


# -- refusals -----------------------------------------------------------------------------------------------
def _refused(data: bytes, reason: str, field: str):
    with pytest.raises(PacketError) as e:
        egm.parse(data)
    assert e.value.reason == reason and field in str(e.value)


def test_bad_packets_are_refused_naming_the_field():
    q = (0.0,) * 6
    no_header = pb.EgmRobot()
    no_header.planned.joints.joints.extend(q)
    no_seqno = pb.EgmRobot.FromString(no_header.SerializeToString())
    no_seqno.header.tm = 5
    _refused(b"", "malformed", "header.seqno")
    _refused(no_header.SerializeToString(), "malformed", "header.seqno")
    _refused(no_seqno.SerializeToString(), "malformed", "header.seqno")
    _refused(egm.robot_packet(1, 2, (0.0, 0.0, math.nan, 0.0, 0.0, 0.0), q), "joints", "planned.joints")
    _refused(egm.robot_packet(1, 2, (0.0, 0.0, 0.0, math.inf, 0.0, 0.0), q), "joints", "planned.joints")
    _refused(egm.robot_packet(1, 2, q[:5], q), "joints", "planned.joints")
    _refused(egm.robot_packet(1, 2, q + (0.0,), q), "joints", "planned.joints")
    _refused(egm.robot_packet(1, 2, (), q), "joints", "planned.joints")
    _refused(egm.robot_packet(1, 2, q, q, (0.0, math.nan, 0.0, 1.0, 0.0, 0.0, 0.0)), "malformed", "planned.cartesian")
    _refused(egm.joint_answer(1, q), "malformed", "header.mtype")       # a sensor's own answer sent back
    _refused(egm.robot_packet(1, 2, q, q) + _doubles(7, [0.0] * 200), "malformed", "bytes")
    _refused(b"\x0a\x05\x08", "malformed", "EgmRobot")                 # cut short


@settings(max_examples=400, deadline=None)
@given(st.binary(max_size=2000) | st.builds(lambda d, i, b: d[:i] + b + d[i + len(b):],
                                              st.just(egm.robot_packet(9, 9, (1.0,) * 6, (2.0,) * 6,
                                                                       (1.0, 2.0, 3.0, 1.0, 0.0, 0.0, 0.0))),
                                              st.integers(0, 210), st.binary(min_size=1, max_size=4)))
def test_any_datagram_is_read_or_refused(data):
    """Random bytes, and a good packet with a few bytes overwritten: a RobotPacket or a PacketError."""
    for f in (egm.parse, egm.read_answer):
        try:
            out = f(data)
        except PacketError as e:
            assert e.reason in ("malformed", "joints")
            continue
        if f is egm.parse:
            assert len(out.joints_deg) == 6 and all(math.isfinite(v) for v in out.joints_deg)


def test_answers_that_are_not_answers_are_refused():
    for data in (b"", egm.robot_packet(1, 2, (0.0,) * 6, (0.0,) * 6), b"\xff\xff\xff",
                 egm.joint_answer(1, (0.0,) * 6) + _doubles(3, [0.0] * 200)):
        with pytest.raises(PacketError):
            egm.read_answer(data)


# -- the path frame -----------------------------------------------------------------------------------------
def _dot(a, b) -> float:
    return sum(x * y for x, y in zip(a, b))


def _flat(frame) -> list[float]:
    return [c for row in frame for c in row]


def _is_right_handed_orthonormal(frame) -> None:
    for i in range(3):
        for j in range(3):
            assert _dot(frame[i], frame[j]) == pytest.approx(float(i == j), abs=1e-9)
    assert egm._cross(frame[0], frame[1]) == pytest.approx(frame[2], abs=1e-9)


@given(p=poses, step=st.tuples(*[st.floats(-10, 10)] * 3))
def test_the_path_frame_is_abbs(p, step):
    """x along the motion, y = x * tool z, z = x * y: orthonormal, right-handed, z against the tool's z."""
    _, z_tool = egm.tool_axes(p[3:])
    n = math.sqrt(_dot(step, step))
    assume(n > 1e-3)
    x = tuple(s / n for s in step)
    assume(math.sqrt(_dot(egm._cross(x, z_tool), egm._cross(x, z_tool))) > 1e-3)
    frame = egm.path_frame(p, (p[0] + step[0], p[1] + step[1], p[2] + step[2], *p[3:]))
    _is_right_handed_orthonormal(frame)
    assert frame[0] == pytest.approx(x, abs=1e-9)
    assert _dot(frame[1], z_tool) == pytest.approx(0.0, abs=1e-9)
    assert _dot(frame[2], z_tool) < 0
    d = (step[1], -step[2], step[0])
    assert egm.to_base(frame, egm.to_path(frame, d)) == pytest.approx(d, abs=1e-9)


@given(p=poses, x_prev=st.tuples(*[st.floats(-1, 1)] * 3), creep=st.tuples(*[st.floats(-3e-5, 3e-5)] * 3))
def test_a_standing_tcp_keeps_the_previous_x_or_takes_the_tools(p, x_prev, creep):
    """Moved less than MIN_STEP_MM: x is the previous frame's, or the tool's x when there is none or it
    lies along the tool's z."""
    x_tool, z_tool = egm.tool_axes(p[3:])
    n = math.sqrt(_dot(x_prev, x_prev))
    assume(n > 0.1)
    x = tuple(c / n for c in x_prev)
    assume(math.sqrt(_dot(egm._cross(x, z_tool), egm._cross(x, z_tool))) > 1e-3)
    moved = (p[0] + creep[0], p[1] + creep[1], p[2] + creep[2], *p[3:])
    frame = egm.path_frame(p, moved, x_prev)
    _is_right_handed_orthonormal(frame)
    assert frame[0] == pytest.approx(x, abs=1e-9)
    for prev in (None, (0.0, 0.0, 0.0), z_tool, tuple(-c for c in z_tool)):
        frame = egm.path_frame(p, moved, prev)
        _is_right_handed_orthonormal(frame)
        assert frame[0] == pytest.approx(x_tool, abs=1e-9)


def test_a_downward_tool_moving_along_base_x():
    """Tool z down (180 deg about x): path x = +X, y = x * (-Z) = +Y, z = +Z (up, away from the work)."""
    frame = egm.path_frame((0, 0, 0, 0, 1, 0, 0), (0.4, 0, 0, 0, 1, 0, 0))
    assert _flat(frame) == pytest.approx([1, 0, 0, 0, 1, 0, 0, 0, 1], abs=1e-12)
    plunge = egm.path_frame((0, 0, 0, 0, 1, 0, 0), (0, 0, -0.4, 0, 1, 0, 0), x_prev=(0, 1, 0))
    assert plunge[0] == pytest.approx((0, 1, 0))          # along the tool's z: the previous x


# -- the generated code -------------------------------------------------------------------------------------
def _gencode(path: Path) -> tuple[bytes, tuple[int, int, int]]:
    """The serialized descriptor and the runtime version a protoc-generated _pb2.py demands."""
    blob = version = None
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute):
            if node.func.attr == "AddSerializedFile":
                blob = node.args[0].value
            elif node.func.attr == "ValidateProtobufRuntimeVersion":
                version = tuple(a.value for a in node.args[1:4])
    return blob, version


def test_the_protobuf_floor_is_what_the_generated_code_demands():
    deps = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["dependencies"]
    floor = next(d.split(">=")[1] for d in deps if d.startswith("protobuf>="))
    assert ".".join(map(str, _gencode(ROBOT / "egm_pb2.py")[1])) == floor


@pytest.mark.skipif(importlib.util.find_spec("grpc_tools") is None,
                    reason="grpcio-tools (the test extras) is not installed: protoc cannot regenerate egm_pb2.py")
def test_egm_pb2_is_protocs_code_for_egm_proto(tmp_path):
    subprocess.run([sys.executable, "-m", "grpc_tools.protoc", f"-I{ROBOT}", f"--python_out={tmp_path}",
                    str(ROBOT / "egm.proto")], check=True, timeout=120)
    fresh, committed = tmp_path / "egm_pb2.py", ROBOT / "egm_pb2.py"
    assert _gencode(fresh)[0] == _gencode(committed)[0], "egm.proto changed: run `make egm-proto`"
    if _gencode(fresh)[1] == _gencode(committed)[1]:        # the same protoc writes the same file
        assert fresh.read_text() == committed.read_text()

