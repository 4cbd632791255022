"""What the robot road's packet-by-packet tests share: the model's robot, a pose, a clock of the test's own, a
process image, and a correction published into it as the cycle would."""

from __future__ import annotations

from hil.testing import CONFIG
from plc_link.contract import to_plc
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from stiffness.kinematics.robot import load_robot

ROBOT = load_robot(CONFIG / "robots" / "kr125.yaml")
Q = [0.0, -60.0, 90.0, 0.0, 60.0, 0.0]
ROBOT_AT = ("127.0.0.1", 40000)
LIMITS = [(float(lo), float(hi)) for lo, hi in ROBOT.limits_deg]


class Clock:
    """Monotonic seconds the test moves by hand."""

    def __init__(self):
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def new_image() -> ProcessImage:
    return ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))


def publish(image, correction, fault_word: int = 0) -> None:
    """The cycle's newest to_plc block with this joint correction (deg) and fault word."""
    image.publish(to_plc(fault_word=fault_word, **{f"correction_q{i + 1}": float(v) for i, v in enumerate(correction)}))
