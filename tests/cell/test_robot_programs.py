"""The committed robot programs (robot/) are `stiffcomp robot-programs`' output, byte for byte, and the generators
write programs their writers accept for any plan in range: the RAPID probe log's longest string stays within 80
characters whatever the frames, radii and joints, and its log reads back."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_probe_programs import krl_data, rapid_code, rapid_env

from cell.robot import egm, probe_krl, probe_rapid
from cell.robot.plan import ProbePlan, load_probe_plan
from cell.robot.programs import generate
from robot_road.settings import RobotSettings
from stiffness.data.probe_log import read_probe
from stiffness.errors import ConfigError
from testlib.common import ROOT
from testlib.robot_logs import krl_log, rapid_log
from tools.cli import main

ROBOT_DIR = ROOT / "cell" / "robot" / "generated"


def test_the_committed_programs_are_the_generators_output():
    files = generate().files
    assert sorted(files) == sorted(str(p.relative_to(ROBOT_DIR)) for p in ROBOT_DIR.rglob("*") if p.is_file())
    for rel, text in files.items():
        assert (ROBOT_DIR / rel).read_bytes() == text.encode("ascii"), rel


def test_the_command_writes_them_and_says_what_the_kuka_config_must_change(tmp_path, capsys):
    """The shipped configs write the committed files without a note; a KUKA config at 4 ms is told to say 12."""
    assert main(["robot-programs", "-o", str(tmp_path / "out")]) == 0
    for path in ROBOT_DIR.rglob("*"):
        if path.is_file():
            assert (tmp_path / "out" / path.relative_to(ROBOT_DIR)).read_bytes() == path.read_bytes()
    assert "cycle_ms" not in capsys.readouterr().err
    fast = tmp_path / "rsi4.yaml"
    fast.write_text((ROOT / "config" / "robot_kuka_rsi.yaml").read_text().replace("cycle_ms: 12 ", "cycle_ms: 4  "))
    assert "cycle_ms: 4 " in fast.read_text()
    assert main(["robot-programs", "-o", str(tmp_path / "out4"), "--config", str(fast)]) == 0
    err = capsys.readouterr().err
    assert "robot.kuka_rsi.cycle_ms is 4" in err and "set robot.kuka_rsi.cycle_ms: 12" in err


def test_the_command_refuses_two_configs_of_one_interface(tmp_path, capsys):
    cfg = str(ROOT / "config" / "robot_abb_egm.yaml")
    assert main(["robot-programs", "-o", str(tmp_path / "o"), "--config", cfg, "--config", cfg]) == 2
    assert "give one config for each" in capsys.readouterr().err


def test_the_plan_is_the_hil_scenarios():
    plan = load_probe_plan()
    assert (plan.touches, plan.path_radius_mm, plan.tool_radius_mm, plan.probe_xyz_mm) == (120, 35.0, 4.0,
                                                                                            (0.0, 0.0, 250.0))


def test_egm_refuses_a_max_deviation_at_the_correction_limit():
    with pytest.raises(ConfigError, match="MaxPosDeviation"):
        egm.egm_modx(RobotSettings(interface="abb_egm"), egm.MAX_DEV_DEG, 200)


PLANS = st.builds(
    ProbePlan, touches=st.integers(2, 999), mask_deg=st.floats(0, 170), path_radius_mm=st.floats(10, 5000),
    tool_radius_mm=st.floats(0.5, 500), stylus_radius_mm=st.floats(0.1, 5), speed_mm_s=st.floats(0.1, 1000),
    latency_ms=st.floats(0, 100), depth_mm=st.floats(0, 1000),
    probe_xyz_mm=st.tuples(*[st.floats(-5000, 5000)] * 3), probe_rpy_deg=st.tuples(*[st.floats(-180, 180)] * 3))
JOINTS = st.lists(st.floats(-400, 400), min_size=6, max_size=6)


@settings(max_examples=40, deadline=None)
@given(PLANS, JOINTS, st.floats(0, 2 * np.pi))
def test_any_plan_gives_a_rapid_log_within_80_that_reads_back(tmp_path_factory, plan, q, phi):
    mod = probe_rapid.probe_modx(plan)
    code = rapid_code(mod)
    env = rapid_env(dict(re.findall(r"CONST\s+num\s+(\w+)\s*:=\s*([-+\d.eE]+)\s*;", code)),
                    dict(re.findall(r"CONST\s+pos\s+(\w+)\s*:=\s*\[([^\]]*)\]", code)))
    d = np.array([np.cos(phi), np.sin(phi), 0.0])
    strings = []
    path = tmp_path_factory.mktemp("p") / "probe.csv"
    path.write_text(rapid_log(mod, env, [(np.array(q), d)] * 3, strings))
    assert max(len(s) for s in strings) <= 80
    log = read_probe(path)
    assert np.abs(log.q_deg - np.array(q)).max() <= 1e-6 and log.tool_radius_mm == pytest.approx(plan.tool_radius_mm)
    assert np.allclose(log.probe_frame.xyz_mm, plan.probe_xyz_mm, atol=1e-4)


@settings(max_examples=40, deadline=None)
@given(PLANS, JOINTS)
def test_any_plan_gives_a_krl_program_whose_log_reads_back(tmp_path_factory, plan, q):
    src, dat = probe_krl.probe_src(), probe_krl.probe_dat(plan)
    path = tmp_path_factory.mktemp("k") / "probe.csv"
    path.write_text(krl_log(src, krl_data(dat), [(np.array(q), 0.0, 1.0)] * 3))
    log = read_probe(path)
    assert np.abs(log.q_deg - np.array(q)).max() <= 1e-6
    assert log.stylus_radius_mm == pytest.approx(plan.stylus_radius_mm, abs=1e-6)


def test_a_plan_out_of_range_is_refused():
    with pytest.raises(ConfigError, match="touches"):
        dataclasses.replace(load_probe_plan(), touches=1)
