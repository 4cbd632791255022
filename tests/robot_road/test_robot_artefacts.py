"""The robot road against packets nobody here wrote (tests/data/robot/README.md): the first packet of
ros-industrial's KUKA RSI simulator is read and answered as that simulator reads an answer."""

from __future__ import annotations

import hashlib
from pathlib import Path

import defusedxml.ElementTree as DET
import pytest

from hil.testing import CONFIG
from plc_link.contract import to_plc
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from robot_road import rsi
from robot_road.kuka_rsi import KukaRsiSettings
from robot_road.road import RoadSettings, RobotRoad
from robot_road.settings import RobotSettings

DATA = Path(__file__).resolve().parent.parent / "data" / "robot"
SIMULATOR = DATA / "kuka_rsi_simulator_first_packet.xml"


def test_the_fixture_is_the_one_its_readme_names():
    digest = hashlib.sha256(SIMULATOR.read_bytes()).hexdigest()
    assert digest in (DATA / "README.md").read_text()


def test_the_simulators_packet_is_read():
    p = rsi.parse(SIMULATOR.read_bytes(), KukaRsiSettings())
    assert p.stamp == 0 and p.late == 0
    assert p.joints_deg == (0.0, -90.0, 90.0, 0.0, 90.0, 0.0) == p.setpoint_deg == p.actual_deg


def test_the_road_answers_it_as_the_simulator_reads_an_answer():
    image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    try:
        road = RobotRoad(image, RoadSettings(RobotSettings(interface="kuka_rsi"), enable_on_start=True, ramp_s=0.0))
        image.publish(to_plc(**{f"correction_q{i}": 0.01 * i for i in range(1, 7)}))
        answer = road.received(SIMULATOR.read_bytes(), ("127.0.0.1", 49152))
    finally:
        image.close()
    root = DET.fromstring(answer)                          # as the simulator's parse_rsi_xml_sen reads it
    ak = root.find("AK").attrib
    assert [float(ak[f"A{i}"]) for i in range(1, 7)] == pytest.approx([0.01 * i for i in range(1, 7)], abs=1e-6)
    assert int(root.find("IPOC").text) == 0 and root.get("Type") == "ImFree"
