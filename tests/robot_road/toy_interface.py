"""A toy robot interface, added as another package would add one: this one module and its one declaration.

The protocol is made up for the test, plain text over UDP. Each cycle the robot sends ``TOY <seq> <q1> ... <q6>``
(its packet count and programmed joints, deg) and takes ``ACK <seq> <dq1> ... <dq6>``, the joint correction it
then holds (deg) until the next answer. The robot's cycle is ``robot.toy.cycle_ms``.

Nothing of the project names it: the road, the HIL and ``stiffcomp run --check`` find it by its declaration,
whether its module is imported or its entry point (group ``stiffcomp.robot_interfaces``) is installed.
"""

from __future__ import annotations

import numpy as np
from pydantic import Field

from hil.virtual_robot import RobotController
from robot_road.interface import RobotInterface
from robot_road.packets import PacketError, RobotPacket
from robot_road.registry import Declaration, declare
from stiffness.files.yaml_schema import Strict


class ToySettings(Strict):
    """``robot.toy``: the toy robot's cycle."""

    cycle_ms: int = Field(8, ge=1, le=100)

    @property
    def cartesian_answer(self) -> bool:
        return False

    @property
    def command_element(self) -> None:
        return None

    def served(self) -> str:
        return f"{self.cycle_ms} ms, joints"

    def follows_no_path(self) -> None:
        return None


def _numbers(data: bytes, word: bytes) -> tuple[int, tuple[float, ...]]:
    parts = data.split()
    if len(parts) != 8 or parts[0] != word:
        raise PacketError("malformed", f"not a toy {word.decode()} packet: {data[:40]!r}")
    try:
        return int(parts[1]), tuple(float(x) for x in parts[2:])
    except ValueError as e:
        raise PacketError("malformed", f"a toy packet with a field that is no number: {e}") from e


class ToyInterface(RobotInterface):
    """The road's side: the programmed joints are the packet's, the answer the joint correction."""

    stamp_name = "seq"
    stamp_unit = "packets"

    def parse(self, data: bytes) -> RobotPacket:
        seq, q = _numbers(data, b"TOY")
        if not all(np.isfinite(q)):
            raise PacketError("joints", "a toy packet with joints that are not finite")
        return RobotPacket(seq, q)

    def programmed(self, p: RobotPacket, held, new_session: bool) -> list[float]:
        return list(p.joints_deg)

    def answer(self, p: RobotPacket, q: list[float], correction: list[float], age_ms: float) -> bytes:
        self.hold(correction, correction)
        return (f"ACK {p.stamp} " + " ".join(f"{c:.9f}" for c in correction)).encode()


class ToyController(RobotController):
    """The HIL's side: a robot that sends its programmed joints each cycle and holds the last correction."""

    def __init__(self, settings, robot, delay_s: float = 0.0):
        super().__init__(settings, robot, delay_s)
        self.period = settings.section.cycle_ms / 1000.0
        self.restart()

    def restart(self) -> None:
        self.stamp = 0
        self.held = np.zeros(6)

    def packet(self, t: float, q_ref) -> bytes:
        self.stamp += 1
        return (f"TOY {self.stamp} " + " ".join(f"{q:.6f}" for q in q_ref)).encode()

    def take(self, data: bytes, t: float, q_ref) -> bool:
        try:
            seq, values = _numbers(data, b"ACK")
        except PacketError:
            return False
        if seq != self.stamp:
            return False
        self.answer = values
        self.held = np.array(values)
        return True

    def commanded(self, t: float, q_ref) -> np.ndarray:
        return np.asarray(q_ref, dtype=float) + self.held

    def holds(self, t: float, q_ref) -> np.ndarray:
        return self.held.copy()


DECLARATION = declare(Declaration("toy", "Toy robot", ToySettings, ToyInterface, "toy_interface:ToyController"))
