"""KUKA RSI (Robot Sensor Interface) over Ethernet: the robot's XML packet read, the sensor's answer written.

The robot sends, every RSI cycle (4 ms on a KR C4), one UDP datagram::

    <Rob TYPE="KUKA">
      <RIst X="..." Y="..." Z="..." A="..." B="..." C="..."/>   Cartesian actual (mm, deg)
      <AIPos A1="..." ... A6="..."/>                            axes' actual positions (deg)
      <ASPos A1="..." ... A6="..."/>                            axes' setpoints (deg)
      <Delay D="0"/>                                            late answers so far
      <IPOC>4208275</IPOC>                                      the robot's time stamp (ms)
    </Rob>

and expects, within the same cycle, ``<Sen Type="ImFree"><AK A1=".." .. A6=".."/><IPOC>4208275</IPOC></Sen>``
(or ``<RKorr X Y Z A B C/>``), the IPOC repeated. Elements the RSI configuration adds to the packet (a command
word, a heartbeat, the payload index) come as ``<Name>value</Name>``.

The packet is parsed by defusedxml with DTDs forbidden: a document type declaration, an entity or an external
reference is refused before anything is expanded.
"""

from __future__ import annotations

import math
from xml.etree.ElementTree import ParseError

import defusedxml.ElementTree as DET
from defusedxml import DefusedXmlException

from .packets import PacketError, RobotPacket

AXES = ("A1", "A2", "A3", "A4", "A5", "A6")
CARTESIAN = ("X", "Y", "Z", "A", "B", "C")
MAX_BYTES = 4096            # an RSI packet is a few hundred bytes; a longer one is not the robot's


def _int(root, name: str, detail: str) -> int | None:
    e = root.find(name)
    if e is None:
        return None
    try:
        return int((e.text or "").strip())
    except ValueError:
        raise PacketError("malformed", f"<{name}> = {e.text!r} {detail}") from None


def parse(data: bytes, s) -> RobotPacket:
    """One ``<Rob>`` packet; PacketError (reason ``malformed``, ``ipoc`` or ``joints``) when it is not whole."""
    if len(data) > MAX_BYTES:
        raise PacketError("malformed", f"{len(data)} bytes, more than an RSI packet's {MAX_BYTES}")
    try:
        root = DET.fromstring(data, forbid_dtd=True)
    except (ParseError, DefusedXmlException, ValueError) as e:
        raise PacketError("malformed", f"not RSI XML: {e}") from None
    if root.tag != "Rob":
        raise PacketError("malformed", f"the root element is <{root.tag}>, not <Rob>")
    ipoc = root.find("IPOC")
    try:
        stamp = int((ipoc.text or "").strip()) if ipoc is not None else -1
    except ValueError:
        stamp = -1
    if stamp < 0:
        raise PacketError("ipoc", "no <IPOC> with a whole number >= 0")
    q = _axes(root, s.joints, required=True)
    other = _axes(root, "AIPos" if s.joints == "ASPos" else "ASPos", required=False)
    setpoint, actual = (q, other) if s.joints == "ASPos" else (other, q)
    delay = root.find("Delay")
    try:
        late = int(delay.get("D")) if delay is not None else None
    except (TypeError, ValueError):
        raise PacketError("malformed", "<Delay D> is not a whole number") from None
    extra = {k: None if n is None else _int(root, n, f"(robot.kuka_rsi.{k}_element) is not a whole number")
             for k, n in (("command", s.command_element), ("heartbeat", s.heartbeat_element),
                          ("payload", s.payload_element))}
    return RobotPacket(stamp, q, late, **extra, setpoint_deg=setpoint, actual_deg=actual)


def _axes(root, tag: str, required: bool) -> tuple[float, ...] | None:
    """A1..A6 of ``<tag>`` (deg); None for an absent optional element or one that is not six finite numbers."""
    axes = root.find(tag)
    if axes is None:
        if required:
            raise PacketError("joints", f"no <{tag}> element (robot.kuka_rsi.joints)")
        return None
    try:
        q = tuple(float(axes.get(a, "nan")) for a in AXES)
    except ValueError:
        if not required:
            return None
        raise PacketError("joints", f"<{tag}> has a value that is not a number") from None
    if not all(math.isfinite(v) for v in q):
        if not required:
            return None
        raise PacketError("joints", f"<{tag}> A1..A6 = {q}: not six finite numbers")
    return q


def answer(sen_type: str, ipoc: int, values, cartesian: bool) -> bytes:
    """The ``<Sen>`` answer: AK A1..A6 (deg) or RKorr X Y Z (mm) A B C (deg), and the packet's IPOC."""
    tag, names = ("RKorr", CARTESIAN) if cartesian else ("AK", AXES)
    attrs = " ".join(f'{n}="{v:.6f}"' for n, v in zip(names, values))
    return f'<Sen Type="{sen_type}"><{tag} {attrs} /><IPOC>{ipoc}</IPOC></Sen>'.encode()


# -- the robot's side (the HIL's virtual robot, the benchmark) ---------------------------------------------
def robot_packet(ipoc: int, setpoint_deg, actual_deg, delay: int = 0, extra: dict[str, int] | None = None) -> bytes:
    """A ``<Rob TYPE="KUKA">`` packet as a KR C4 sends it, with ``extra`` elements (name: value)."""
    def axes(tag: str, q) -> str:
        return f"<{tag} " + " ".join(f'{a}="{v:.6f}"' for a, v in zip(AXES, q)) + " />"
    more = "".join(f"<{k}>{int(v)}</{k}>" for k, v in (extra or {}).items())
    return (f'<Rob TYPE="KUKA">{axes("AIPos", actual_deg)}{axes("ASPos", setpoint_deg)}'
            f'<Delay D="{int(delay)}" />{more}<IPOC>{int(ipoc)}</IPOC></Rob>').encode()


def read_answer(data: bytes) -> tuple[int, str, tuple[float, ...]]:
    """(IPOC, ``AK`` or ``RKorr``, its six values) of a ``<Sen>`` answer; PacketError when it is not one."""
    try:
        root = DET.fromstring(data, forbid_dtd=True)
    except (ParseError, DefusedXmlException, ValueError) as e:
        raise PacketError("malformed", f"not an RSI answer: {e}") from None
    ipoc = _int(root, "IPOC", "is not a whole number")
    for tag, names in (("AK", AXES), ("RKorr", CARTESIAN)):
        e = root.find(tag)
        if root.tag == "Sen" and e is not None and ipoc is not None:
            try:
                return ipoc, tag, tuple(float(e.get(n)) for n in names)
            except (TypeError, ValueError):
                break
    raise PacketError("malformed", "not a <Sen> answer with IPOC and AK or RKorr")
