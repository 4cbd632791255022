"""A third robot interface is one module and its one declaration (`toy_interface`, a protocol made up here): the road
answers it, the HIL's virtual controller registry drives it, `stiffcomp run --check` checks its port, and the
running service serves it, found through an entry point as an installed package's would be, with no file of the
project touched."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import toy_interface
from toy_interface import ToyController, ToyInterface

from hil.robot_drive import drive
from hil.run import ServiceProcess
from hil.testing import CONFIG, free_port, write_config
from hil.virtual_robot import VirtualRobot, controller_for
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from robot_road import registry
from robot_road.road import RoadSettings, RobotRoad
from robot_road.session import Phase
from robot_road.settings import RobotSettings
from stiffness.kinematics.robot import load_robot
from testlib.common import ROOT
from testlib.road import Clock, publish

ROBOT = load_robot(CONFIG / "robots" / "kr125.yaml")
Q = [0.0, -60.0, 90.0, 0.0, 60.0, 0.0]
HERE = Path(__file__).resolve().parent


def settings(**section) -> RobotSettings:
    return RobotSettings.model_validate({"interface": "toy", "toy": section})


def test_the_declaration_is_all_the_config_and_the_registries_need():
    s = settings(cycle_ms=6)
    assert "toy" in registry.names() and s.declaration is toy_interface.DECLARATION
    assert s.section.cycle_ms == 6 and s.cycle_ms == 6 and s.served() == "Toy robot on 127.0.0.1:49152 (6 ms, joints)"
    assert isinstance(controller_for(s, ROBOT), ToyController)
    with pytest.raises(ValueError, match=r"toy\.cycle_ms"):
        settings(cycle_ms=0)
    with pytest.raises(ValueError, match=r"toy\.bogus"):
        settings(bogus=1)


def test_the_road_answers_the_toy_and_drops_what_is_not_its_packet():
    image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    clock = Clock()
    road = RobotRoad(image, RoadSettings(settings(), ramp_s=0.0), clock=clock)
    assert isinstance(road.iface, ToyInterface) and road.sessions.phase(clock()) is Phase.AWAITING
    correction = [0.01, -0.02, 0.03, 0.0, 0.005, -0.004]
    publish(image, correction)
    robot = controller_for(road.settings.robot, ROBOT)
    for k in range(3):
        clock.t += 0.008
        packet = robot.packet(clock.t, Q)
        assert robot.take(road.received(packet, ("127.0.0.1", 40000)), clock.t, Q), k
    assert np.allclose(robot.held, correction, atol=1e-9)
    assert road.received(b"TOY 4 1 2 3", ("127.0.0.1", 40000)) is None
    report = road.report()
    assert report.counts.answered == 3 and report.counts.dropped == {"malformed": 1}
    assert report.sessions == 1 and report.phase is Phase.ANSWERING and report.interface == "toy"


@pytest.fixture
def installed(tmp_path, monkeypatch):
    """The toy as an installed package's interface: an entry point in a distribution's metadata on the path of
    the processes the test starts."""
    dist = tmp_path / "site" / "stiffcomp_toy-0.1.dist-info"
    dist.mkdir(parents=True)
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: stiffcomp-toy\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[{registry.ENTRY_POINTS}]\ntoy = toy_interface\n")
    path = os.pathsep.join([str(tmp_path / "site"), str(HERE), str(ROOT), os.environ.get("PYTHONPATH", "")])
    monkeypatch.setenv("PYTHONPATH", path)
    return path


def test_run_check_checks_the_toys_port(tmp_path, installed):
    port = free_port(socket.SOCK_DGRAM)
    cfg = write_config(tmp_path, {"plc": {"role": "none"}, "robot": {"interface": "toy", "port": port,
                                                                      "toy": {"cycle_ms": 8}}})
    done = subprocess.run([sys.executable, "-m", "tools.cli", "run", "--check", "--config", str(cfg)], cwd=ROOT,
                          capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 0, done.stderr
    assert f"robot.port 127.0.0.1:{port}/udp free" in done.stdout + done.stderr
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", port))
        done = subprocess.run([sys.executable, "-m", "tools.cli", "run", "--check", "--config", str(cfg)],
                              cwd=ROOT, capture_output=True, text=True, timeout=120, check=False)
    assert done.returncode == 2 and f"robot.port = {port}" in done.stderr, done.stderr


@pytest.mark.realtime
def test_the_running_service_answers_the_toy_robot(tmp_path, installed):
    port = free_port(socket.SOCK_DGRAM)
    cfg = write_config(tmp_path, {"plc": {"role": "none", "enable_on_start": True},
                                  "robot": {"interface": "toy", "port": port, "toy": {"cycle_ms": 8}}})
    service = ServiceProcess(cfg, tmp_path)
    try:
        service.wait_running()
        vr = VirtualRobot(controller_for(settings(cycle_ms=8), ROBOT), "127.0.0.1", port, lambda t: Q)
        try:
            d = drive(vr, 1.0, time.monotonic())
        finally:
            vr.close()
    finally:
        service.stop()
    stats, _ = service.result()
    road = stats["robot"]
    # one session, and one more after each silence of the robot's own (a stalled host) beyond the road's 200 ms
    # (give or take 10 ms: the robot's clock and the road's)
    assert road["interface"] == "toy" and road["dropped"] == {}, road
    assert 1 + d.silences(0.21) <= road["sessions"] <= 1 + d.silences(0.19), road
    assert road["packets"] == road["answered"] == len(d.answered) > 0, road
    assert d.answered.sum() >= 0.9 * len(d.answered)
