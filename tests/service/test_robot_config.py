"""The ``robot`` section in the service config: what it takes, refuses, and warns about."""

from __future__ import annotations

import pytest

from hil.testing import write_config
from robot_road.settings import RobotSettings
from service.compensation import load_model
from service.config import load_config
from service.errors import ServiceConfigError
from service.io_config import io_settings


def test_the_default_is_no_robot_road_and_the_io_process_gets_none(tmp_path):
    cfg = load_config(write_config(tmp_path))
    assert cfg.robot.interface == "none" and io_settings(cfg, load_model(cfg).robot).robot is None


def test_a_road_without_a_plc_owns_the_commands_and_takes_the_faults_timeout_and_ramp(tmp_path):
    cfg = load_config(write_config(tmp_path, {"plc": {"role": "none"},
                                              "robot": {"interface": "abb_egm", "abb_egm": {"mode": "joint"}},
                                              "faults": {"plc_heartbeat_timeout_ms": 80}, "limits": {"fault_ramp_s": 0.3}}))
    road = io_settings(cfg, load_model(cfg).robot).robot
    assert road.owns_commands and road.silence_s == pytest.approx(0.08) and road.ramp_s == 0.3
    assert road.robot_file is None and len(road.limits_deg) == 6          # joint mode: no kinematics needed


@pytest.mark.parametrize("overrides, words", [
    ({"robot": {"interface": "kuka_rsi", "realtime_priority": 50}, "cycle": {"realtime_priority": 50}},
     ["robot.realtime_priority = 50", "cycle.realtime_priority (50)"]),
    ({"robot": {"interface": "kuka_rsi"}, "faults": {"plc_heartbeat_timeout_ms": 8}},
     ["faults.plc_heartbeat_timeout_ms = 8", "cycle_ms = 4"]),
    ({"robot": {"interface": "kuka_rsi", "kuka_rsi": {"cycle_ms": 5}}}, ["robot.kuka_rsi.cycle_ms"]),
    ({"robot": {"interface": "abb_egm", "peer": "robot-1"}}, ["robot.peer"]),
    ({"robot": {"interface": "abb_egm"}, "faults": {"plc_heartbeat_timeout_ms": 80}},      # path mode: 48 ms
     ["faults.plc_heartbeat_timeout_ms = 80", "abb_egm cycle_ms = 48"]),
    ({"robot": {"interface": "kuka_rsi", "kuka_rsi": {"sen_type": "Im Free"}}}, ["robot.kuka_rsi.sen_type"]),
])
def test_a_bad_robot_section_is_refused_naming_the_key(tmp_path, overrides, words):
    with pytest.raises(ServiceConfigError) as e:
        load_config(write_config(tmp_path, overrides))
    assert all(w in str(e.value) for w in words), str(e.value)


def test_a_road_open_beyond_this_machine_to_any_sender_is_warned_about():
    assert "robot.peer" in RobotSettings(interface="kuka_rsi", host="0.0.0.0").exposure_warning()
    assert RobotSettings(interface="kuka_rsi", host="0.0.0.0", peer="192.168.1.20").exposure_warning() is None
    assert RobotSettings(interface="kuka_rsi", host="127.0.0.1").exposure_warning() is None
    assert RobotSettings(interface="none", host="0.0.0.0").exposure_warning() is None


@pytest.mark.parametrize("section, element", [
    ({"interface": "kuka_rsi", "kuka_rsi": {"command_element": "StiffCmd"}}, "StiffCmd"),
    ({"interface": "kuka_rsi"}, None),
    ({"interface": "abb_egm"}, None),                                   # EGM's messages carry no command word
    ({"interface": "none", "kuka_rsi": {"command_element": "StiffCmd"}}, None),      # no road, no element
])
def test_the_robots_own_command_element_is_the_sub_sections_of_the_interface_in_use(section, element):
    assert RobotSettings.model_validate(section).command_element == element


@pytest.mark.parametrize("section, follows", [
    ({"interface": "kuka_rsi"}, True), ({"interface": "abb_egm"}, True),
    ({"interface": "abb_egm", "abb_egm": {"mode": "joint"}}, False),
])
def test_only_egm_position_guidance_says_it_runs_no_path(section, follows):
    why = RobotSettings.model_validate(section).section.follows_no_path()
    assert (why is None) == follows and (follows or "position guidance" in why)
