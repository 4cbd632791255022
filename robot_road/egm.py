"""ABB EGM (Externally Guided Motion): the robot's ``EgmRobot`` read, the sensor's answer written.

The robot sends, every EGM cycle (4 ms by default), one UDP datagram: an ``EgmRobot`` message of ABB's
egm.proto (``egm.proto`` here holds the part of it the road needs; ``egm_pb2`` is protoc's code for it, made
by ``make egm-proto``) with its header (``seqno``, its own count, ``tm``, its clock in ms, type
MSGTYPE_DATA), the measured (``feedBack``) and programmed (``planned``) joints in degrees and TCP pose (mm and
a unit quaternion), and the motor, EGM and RAPID states. The sensor answers with its own header (its own
rising ``seqno``) and either

* ``EgmSensor`` of type MSGTYPE_CORRECTION, position guidance (EGMActJoint, EGMRunJoint): the joints the
  robot shall take, ``planned.joints`` in degrees; or
* ``EgmSensorPathCorr`` of type MSGTYPE_PATH_CORRECTION, path correction (EGMActMove, EGMMoveL/EGMMoveC):
  an offset ``pathCorr.pos`` (mm) in the path frame and ``pathCorr.age``, how old the measurement is (ms).

The path frame, as ABB's Application manual Externally Guided Motion (3HAC073318-001, "Introduction to EGM
Path Correction") defines it: its x axis is the path's tangent, its y axis the cross product of that tangent
and the z axis of the active tool, and its z axis the cross product of x and y. So y = x * z_tool, z = x * y:
a right-handed frame whose z is the tool's z axis made square to the path and turned round (it points
against the tool's z). The same manual says the robot corrects only along y and z (not along the tangent,
nor the orientation), and reads path corrections every 24 ms or a multiple (EGMActMove's SampleRate; its
examples take 48). `path_frame` builds that frame from two consecutive planned poses.

Refused (PacketError, reason ``malformed``): a datagram longer than `MAX_BYTES`, one that does not parse
as an ``EgmRobot``, one without ``header.seqno``, a sensor's own message type, a pose that is not finite;
(reason ``joints``): ``planned.joints`` absent or not six finite numbers. Protobuf's parser takes many byte
strings (an empty one is an empty message), so the header is demanded.

Cost per call on this machine, quiet (protobuf 7.36.2, its upb parser; 20,000 calls, median of 5 runs;
`parse` of a 206-byte packet with joints and pose): `parse` 5.8 us, `joint_answer` 2.5 us, `path_answer`
1.9 us, `path_frame` 2.7 us (`rsi.parse` 22.7 us in the same run); 2 to 3 times that with both cores busy.
"""

from __future__ import annotations

import math

from google.protobuf.message import DecodeError

from . import egm_pb2 as pb
from .packets import PacketError, RobotPacket

AXES = 6
# an EgmRobot with every field RobotWare 7 sends (external axes, clocks, force, RAPID data), each at its
# largest, is 1,160 bytes; a longer datagram is not the robot's
MAX_BYTES = 1400
MIN_STEP_MM = 1e-4          # a planned TCP that moved less than this (mm) between two packets stood still
DATA = pb.EgmHeader.MSGTYPE_DATA
CORRECTION = pb.EgmHeader.MSGTYPE_CORRECTION
PATH_CORRECTION = pb.EgmHeader.MSGTYPE_PATH_CORRECTION
_U32 = 0xFFFFFFFF           # header counts and ages are uint32: the sensor's count wraps as the robot's does


def _joints(values, where: str) -> tuple[float, ...]:
    q = tuple(values)
    if len(q) != AXES or not all(math.isfinite(v) for v in q):
        raise PacketError("joints", f"{where} = {q}: not six finite numbers")
    return q


def parse(data: bytes) -> RobotPacket:
    """One ``EgmRobot`` datagram; PacketError (reason ``malformed`` or ``joints``) when it is not whole."""
    if len(data) > MAX_BYTES:
        raise PacketError("malformed", f"{len(data)} bytes, more than an EgmRobot's {MAX_BYTES}")
    msg = pb.EgmRobot()
    try:
        msg.ParseFromString(data)
    except DecodeError as e:
        raise PacketError("malformed", f"not an EgmRobot: {e}") from None
    h = msg.header
    if not msg.HasField("header") or not h.HasField("seqno"):
        raise PacketError("malformed", "no header.seqno")
    if h.mtype in (CORRECTION, PATH_CORRECTION):
        raise PacketError("malformed", f"header.mtype is {pb.EgmHeader.MessageType.Name(h.mtype)}, a sensor's")
    if not msg.planned.HasField("joints"):
        raise PacketError("joints", "no planned.joints")
    q = _joints(msg.planned.joints.joints, "planned.joints")
    pose, c = None, msg.planned.cartesian
    if msg.planned.HasField("cartesian") and c.HasField("pos") and c.HasField("orient"):
        pose = (c.pos.x, c.pos.y, c.pos.z, c.orient.u0, c.orient.u1, c.orient.u2, c.orient.u3)
        if not all(math.isfinite(v) for v in pose):
            raise PacketError("malformed", f"planned.cartesian = {pose}: not finite")
    fb = msg.feedBack.joints.joints if msg.HasField("feedBack") and msg.feedBack.HasField("joints") else ()
    actual = tuple(fb) if len(fb) == AXES and all(math.isfinite(v) for v in fb) else None
    return RobotPacket(h.seqno, q, None, tm_ms=h.tm if h.HasField("tm") else None, pose=pose, setpoint_deg=q,
                       actual_deg=actual)


def _header(h, seqno: int, mtype: int, tm_ms: int | None) -> None:
    h.seqno = int(seqno) & _U32
    h.mtype = mtype
    if tm_ms is not None:
        h.tm = int(tm_ms) & _U32


def joint_answer(seqno: int, joints_deg, tm_ms: int | None = None) -> bytes:
    """``EgmSensor``, MSGTYPE_CORRECTION: the joints (deg) the robot shall take; ``seqno`` is the sensor's
    own rising count. ValueError when ``joints_deg`` is not six finite numbers."""
    q = tuple(map(float, joints_deg))
    if len(q) != AXES or not all(math.isfinite(v) for v in q):
        raise ValueError(f"an EGM joint answer takes six finite joints (deg), not {q}")
    msg = pb.EgmSensor()
    _header(msg.header, seqno, CORRECTION, tm_ms)
    msg.planned.joints.joints.extend(q)
    return msg.SerializeToString()


def path_answer(seqno: int, pos_mm, age_ms: int, tm_ms: int | None = None) -> bytes:
    """``EgmSensorPathCorr``, MSGTYPE_PATH_CORRECTION: the offset x, y, z (mm) in the path frame
    (`path_frame`) and the age (ms, below 0 sent as 0) of the measurement it comes from."""
    msg = pb.EgmSensorPathCorr()
    _header(msg.header, seqno, PATH_CORRECTION, tm_ms)
    p = msg.pathCorr.pos
    p.x, p.y, p.z = map(float, pos_mm)
    msg.pathCorr.age = min(max(int(age_ms), 0), _U32)
    return msg.SerializeToString()


# -- the robot's side (the HIL's virtual robot, the benchmark) ---------------------------------------------
def robot_packet(seqno: int, tm_ms: int, planned_deg, feedback_deg, pose=None) -> bytes:
    """An ``EgmRobot`` as the controller sends it while EGM runs: MSGTYPE_DATA, measured and planned joints
    (deg), the planned pose (x, y, z in mm, qw, qx, qy, qz) when given, motors on, EGM and RAPID running.
    The values are not checked, so that a test can send a bad packet."""
    msg = pb.EgmRobot()
    _header(msg.header, seqno, DATA, tm_ms)
    msg.feedBack.joints.joints.extend(map(float, feedback_deg))
    msg.planned.joints.joints.extend(map(float, planned_deg))
    if pose is not None:
        c = msg.planned.cartesian
        c.pos.x, c.pos.y, c.pos.z, c.orient.u0, c.orient.u1, c.orient.u2, c.orient.u3 = map(float, pose)
    msg.motorState.state = pb.EgmMotorState.MOTORS_ON
    msg.mciState.state = pb.EgmMCIState.MCI_RUNNING
    msg.rapidExecState.state = pb.EgmRapidCtrlExecState.RAPID_RUNNING
    return msg.SerializeToString()


def read_answer(data: bytes) -> tuple[int, str, tuple[float, ...], int | None, int | None]:
    """(seqno, ``joints`` or ``path``, the six joints or the path offset x, y, z, the age in ms or None, the
    header's tm or None) of a sensor's answer, told apart by its header type; PacketError when it is not one.
    The road's answers repeat, in tm, the tm of the robot's packet they answer (`robot_road.abb_egm`)."""
    for cls, mtype in ((pb.EgmSensor, CORRECTION), (pb.EgmSensorPathCorr, PATH_CORRECTION)):
        msg = cls()
        try:
            msg.ParseFromString(data)
        except DecodeError:
            continue
        h = msg.header
        if len(data) > MAX_BYTES or h.mtype != mtype or not h.HasField("seqno"):
            continue
        tm = h.tm if h.HasField("tm") else None
        if mtype == CORRECTION and msg.planned.HasField("joints"):
            return h.seqno, "joints", _joints(msg.planned.joints.joints, "planned.joints"), None, tm
        if mtype == PATH_CORRECTION and msg.HasField("pathCorr"):
            p = msg.pathCorr
            return h.seqno, "path", (p.pos.x, p.pos.y, p.pos.z), p.age, tm
    raise PacketError("malformed", "not an EgmSensor (MSGTYPE_CORRECTION, planned.joints) nor an "
                      "EgmSensorPathCorr (MSGTYPE_PATH_CORRECTION, pathCorr) with header.seqno")


# -- the path frame of a path correction ----------------------------------------------------------------------
Vec = tuple[float, float, float]


def _cross(a, b) -> Vec:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _unit(v, least: float) -> Vec | None:
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / n, v[1] / n, v[2] / n) if n >= least else None


def tool_axes(quat) -> tuple[Vec, Vec]:
    """The tool's x and z axes in base coordinates from its orientation (qw, qx, qy, qz; normalised here)."""
    n = math.sqrt(sum(c * c for c in quat))
    w, a, b, c = (v / n for v in quat)
    return ((1 - 2 * (b * b + c * c), 2 * (a * b + w * c), 2 * (a * c - w * b)),
            (2 * (a * c + w * b), 2 * (b * c - w * a), 1 - 2 * (a * a + b * b)))


def path_frame(pose_prev, pose, x_prev=None) -> tuple[Vec, Vec, Vec]:
    """The path frame at ``pose`` (x, y, z mm, qw, qx, qy, qz), ABB's definition (module docstring): its x,
    y and z axes in base coordinates, one per row, so that ``frame[i]`` is axis i.

    x is the planned TCP's motion from ``pose_prev`` to ``pose``; when it moved less than `MIN_STEP_MM`, or
    along the tool's z axis (where y is not defined), x is ``x_prev`` (the previous frame's x), else the
    tool's x axis. A vector d in base coordinates is ``to_path(frame, d)`` in the path frame."""
    x_tool, z_tool = tool_axes(pose[3:7])
    step = (pose[0] - pose_prev[0], pose[1] - pose_prev[1], pose[2] - pose_prev[2])
    for x in (_unit(step, MIN_STEP_MM), None if x_prev is None else _unit(x_prev, 1e-9), x_tool):
        y = None if x is None else _unit(_cross(x, z_tool), 1e-6)
        if y is not None:
            return x, y, _cross(x, y)
    raise ValueError(f"no path frame at {pose}")       # not reached: the tool's x is square to its z


class PathFrames:
    """The path frame of each packet in turn, from its planned pose and the one before (`path_frame`): what the
    road answers a path correction in and what the robot reads it in, one rule for both."""

    def __init__(self):
        self.pose = self.x = None

    def next(self, pose) -> tuple[Vec, Vec, Vec]:
        frame = path_frame(self.pose or pose, pose, self.x)
        self.pose, self.x = pose, frame[0]
        return frame


def to_path(frame, d) -> Vec:
    """A base-frame vector ``d`` in the path ``frame``'s coordinates."""
    return tuple(r[0] * d[0] + r[1] * d[1] + r[2] * d[2] for r in frame)


def to_base(frame, v) -> Vec:
    """A vector ``v`` given in the path ``frame`` in base coordinates (what the robot does with pathCorr)."""
    return tuple(v[0] * frame[0][i] + v[1] * frame[1][i] + v[2] * frame[2][i] for i in range(3))
