"""The robot-side probe programs in cell/robot/generated/probe/ (issue 46, item 3) are held to the plan of the HIL's virtual probe
(config/hil/circle.yaml: its probe section, the circle's radius and the tool's), to the robot's tool frame the
HIL writes (config/robots/kr125.yaml's tcp), and to the probe log format `stiffcomp part` reads.

`krl_mismatches` and `rapid_mismatches` list every value that differs; the shipped files give none, and a plan or
a file drifted in one value is named. Each program's log is written as its controller writes it (testlib.robot_logs:
the KRL's StrClear, SWRITE and krl_fwriteln, the RAPID's Write pieces, no escape processing) and read back by the
reader (`stiffness.data.probe_log`).
"""

from __future__ import annotations

import re

import numpy as np
import pytest
import yaml

from hil.scenario import load_scenario
from stiffness.data.probe_log import HEADER, ProbeHeader, read_probe
from testlib.common import ROOT
from testlib.robot_logs import krl_log, kuka_rotation, rapid_log

PROBE = ROOT / "cell" / "robot" / "generated" / "probe"
KRL_SRC, KRL_DAT, RAPID = PROBE / "StiffCompProbe.src", PROBE / "StiffCompProbe.dat", PROBE / "StiffCompProbe.modx"
ROBOT = ROOT / "config" / "robots" / "kr125.yaml"
REQUIRED_KEYS = {k for k, f in ProbeHeader.model_fields.items() if f.is_required()}


def plan() -> dict[str, float]:
    """What each program's constant must be: the HIL's virtual probe of the same plan."""
    sc = load_scenario()
    p = sc.probe
    return {"nTouches": p.touches, "maskDeg": p.entry_exit_mask_deg, "rPath": sc.circle.radius_mm,
            "rTool": sc.milling.tool_diameter_mm / 2.0, "rStylus": p.stylus_radius_mm, "vProbe": p.speed_mm_s,
            "latencyMs": p.latency_ms, "depth": p.depth_mm}


def tool() -> tuple[list[float], list[float]]:
    tcp = yaml.safe_load(ROBOT.read_text())["tcp"]
    return [float(v) for v in tcp["xyz_mm"]], [float(v) for v in tcp["rpy_deg"]]


def _close(a: float, b: float) -> bool:
    return abs(float(a) - float(b)) <= 1e-9 * max(1.0, abs(float(b)))


# -- KUKA KRL -----------------------------------------------------------------------------------------------
def krl_code(text: str) -> str:
    """KRL without its comments (``;`` to the end of the line, outside a string)."""
    return "\n".join(re.sub(r';[^"]*$', "", line) for line in text.splitlines())


def krl_data(dat: str) -> dict:
    """The .dat file's values: numbers by name, frames as dicts of X Y Z A B C."""
    out = {}
    for name, value in re.findall(r"DECL\s+(?:REAL|INT)\s+(\w+)\s*=\s*([-+\d.eE]+)", krl_code(dat)):
        out[name] = float(value)
    for name, body in re.findall(r"DECL\s+FRAME\s+(\w+)\s*=\s*\{([^}]*)\}", krl_code(dat)):
        out[name] = {k: float(v) for k, v in re.findall(r"(\w+)\s+([-+\d.eE]+)", body)}
    return out


def krl_mismatches(want: dict, xyz: list[float], rpy: list[float], src: str, dat: str) -> list[str]:
    """Each value of StiffCompProbe.src and .dat that differs from the plan, the tool frame or the log format."""
    code, data, out = krl_code(src), krl_data(dat), []
    for name, value in want.items():
        if name not in data or not _close(data[name], value):
            out.append(f"{name} {data.get(name)} in StiffCompProbe.dat but the plan wants {value}")
    frame = data.get("probeFrame", {})
    got_xyz = [frame.get(c) for c in "XYZ"]
    got_rpy = [frame.get(c) for c in "CBA"]        # URDF roll-pitch-yaw are KUKA's C, B, A
    if not all(g is not None and _close(g, w) for g, w in zip(got_xyz + got_rpy, xyz + rpy)):
        out.append(f"probeFrame {frame} but the robot's tcp is xyz_mm {xyz}, rpy_deg {rpy}")
    if not re.search(r"INTERRUPT\s+DECL\s+\d+\s+WHEN\s+\$MEAS_PULSE\[\d\]\s*==\s*TRUE\s+DO\s+PROBE_HIT", code):
        out.append("no interrupt on a fast measurement input ($MEAS_PULSE) calling PROBE_HIT")
    hit = re.search(r"DEF\s+PROBE_HIT\b(.*?)\bEND\b", code, re.DOTALL)
    if hit is None or not re.search(r"hit\s*=\s*\$AXIS_INT", hit.group(1)) or "RESUME" not in hit.group(1):
        out.append("PROBE_HIT does not take the latched axes ($AXIS_INT) and RESUME")
    if not re.search(r"\$VEL\.CP\s*=\s*vProbe\s*/\s*1000(\.0)?\s*\n\s*SEARCH\(", code):
        out.append("the search does not run at the probing speed ($VEL.CP = vProbe / 1000 before SEARCH)")
    if not re.search(r"toRoot\s*=\s*INV_POS\(\$ROBROOT\)\s*:\s*\$BASE", code) or \
            not re.search(r"tip\s*=\s*toRoot\s*:\s*tip", code):
        out.append("the approach is not turned from the base's axes into the robot root's (INV_POS($ROBROOT) : $BASE)")
    return out + log_mismatches(krl_log(src, data, [(np.zeros(6), 1.0, 0.0)]), "the KRL's log")


# -- ABB RAPID ----------------------------------------------------------------------------------------------
def rapid_code(text: str) -> str:
    """RAPID without its comments (``!`` to the end of the line, outside a string)."""
    return "\n".join(re.sub(r'![^"]*$', "", line) for line in text.splitlines())


def rapid_mismatches(want: dict, xyz: list[float], rpy: list[float], mod: str) -> list[str]:
    """Each value of StiffCompProbe.modx that differs from the plan, the tool frame or the log format."""
    code, out = rapid_code(mod), []
    consts = dict(re.findall(r"CONST\s+num\s+(\w+)\s*:=\s*([-+\d.eE]+)\s*;", code))
    for name, value in want.items():
        if name not in consts or not _close(consts[name], value):
            out.append(f"{name} {consts.get(name)} in StiffCompProbe.modx but the plan wants {value}")
    pos = dict(re.findall(r"CONST\s+pos\s+(\w+)\s*:=\s*\[([^\]]*)\]", code))
    for name, w in (("PROBE_XYZ", xyz), ("PROBE_RPY", rpy)):
        got = [float(v) for v in pos.get(name, "").split(",") if v.strip()]
        if len(got) != 3 or not all(_close(g, x) for g, x in zip(got, w)):
            out.append(f"{name} {got} but the robot's tcp wants {w}")
    speed = re.search(r"CONST\s+speeddata\s+vSearch\s*:=\s*\[\s*([-+\d.]+)", code)
    if speed is None or "vProbe" not in consts or not _close(speed.group(1), consts["vProbe"]):
        out.append(f"vSearch's TCP speed {speed.group(1) if speed else None} is not vProbe")
    if not re.search(r"SearchL\s*\\Stop\s*,\s*\w+\s*,\s*pHit\s*,\s*\w+\s*,\s*vSearch\b", code):
        out.append("no SearchL \\Stop to pHit at vSearch")
    if not re.search(r"CalcJointT\s*\(\s*pHit\b", code):
        out.append("the search point is not turned into joints (CalcJointT(pHit, ...))")
    if not re.search(r"wRot\s*:=\s*PoseMult\(\s*wContour\.uframe\s*,\s*wContour\.oframe\s*\)", code) or \
            not re.search(r"dBase\s*:=\s*PoseVect\(\s*wRot\s*,", code):
        out.append("the approach is not turned from wContour's axes into the robot base's (PoseVect, PoseMult)")
    written = rapid_log(mod, rapid_env(consts, pos), [(np.zeros(6), np.array([1.0, 0.0, 0.0]))], [])
    return out + log_mismatches(written, "the RAPID's log")


# -- the log both write -------------------------------------------------------------------------------------
def rapid_env(consts: dict, pos: dict) -> dict:
    """The module's num CONSTs and its pos CONSTs' components, by the names its statements use."""
    env = {name: float(value) for name, value in consts.items()}
    for name, body in pos.items():
        env.update({f"{name}.{c}": float(v) for c, v in zip("xyz", body.split(","))})
    return env


def log_mismatches(text: str, who: str) -> list[str]:
    """The '#' keys a program writes are the ones the reader knows, the required ones among them, and its header
    row is the format's."""
    out = []
    keys = set(re.findall(r"^# (\w+):", text, re.MULTILINE)) - {"stiffcomp"}
    if not keys <= set(ProbeHeader.model_fields):
        out.append(f"{who} writes keys the reader refuses: {sorted(keys - set(ProbeHeader.model_fields))}")
    if not REQUIRED_KEYS <= keys:
        out.append(f"{who} lacks the key(s) {sorted(REQUIRED_KEYS - keys)}")
    if HEADER not in text.splitlines():
        out.append(f"{who} does not write the header row {HEADER}")
    return out


def shipped():
    return plan(), *tool(), KRL_SRC.read_text(), KRL_DAT.read_text(), RAPID.read_text()


def test_the_probe_programs_match_the_plan_the_tool_and_the_log_format():
    want, xyz, rpy, src, dat, mod = shipped()
    assert krl_mismatches(want, xyz, rpy, src, dat) == []
    assert rapid_mismatches(want, xyz, rpy, mod) == []


Q = np.array([[0.5, -59.6, 89.7, 0.0, 59.9, 0.5], [1.0, -60.0, 90.0, 0.1, 60.0, 0.0],
              [-0.5, -60.4, 90.3, -0.1, 60.1, -0.5]])
PHI = np.radians([10.0, 180.0, 350.0])


@pytest.mark.parametrize("base_abc", [(0.0, 0.0, 0.0), (30.0, 0.0, 0.0), (-45.0, 10.0, 180.0)])
def test_the_log_the_krl_writes_reads_back(tmp_path, base_abc):
    """Three touches as the controller writes StiffCompProbe.src's log (krl_fwriteln ends each line, no escape
    in any literal): the reader takes the joints and the directions, turned into the root's axes where the base is
    rotated."""
    _, _, _, src, dat, _ = shipped()
    data = krl_data(dat)
    touches = [(Q[i], float(np.cos(PHI[i])), float(np.sin(PHI[i]))) for i in range(3)]
    (tmp_path / "probe.csv").write_text(krl_log(src, data, touches, base_abc))
    log = read_probe(tmp_path / "probe.csv")
    assert np.abs(log.q_deg - Q).max() <= 1e-6
    want = (kuka_rotation(*base_abc) @ np.vstack([np.cos(PHI), np.sin(PHI), np.zeros(3)])).T
    assert np.allclose(log.approach, want, atol=1e-6)
    assert log.stylus_radius_mm == data["rStylus"] and log.overtravel_mm == pytest.approx(
        data["vProbe"] * data["latencyMs"] / 1000.0)


def test_the_log_the_rapid_writes_reads_back(tmp_path):
    """Three touches as the controller writes StiffCompProbe.modx's log, in its pieces: the reader takes them."""
    *_, mod = shipped()
    code = rapid_code(mod)
    env = rapid_env(dict(re.findall(r"CONST\s+num\s+(\w+)\s*:=\s*([-+\d.eE]+)\s*;", code)),
                    dict(re.findall(r"CONST\s+pos\s+(\w+)\s*:=\s*\[([^\]]*)\]", code)))
    d = np.column_stack([np.cos(PHI), np.sin(PHI), np.zeros(3)])
    strings = []
    (tmp_path / "probe.csv").write_text(rapid_log(mod, env, [(Q[i], d[i]) for i in range(3)], strings))
    log = read_probe(tmp_path / "probe.csv")
    assert np.abs(log.q_deg - Q).max() <= 1e-6 and np.allclose(log.approach, d, atol=1e-6)
    assert log.tool_radius_mm == env["rTool"] and max(len(t) for t in strings) <= 80


def test_the_old_krl_log_does_not_read_back(tmp_path):
    """The old program's "\\n" in krl_fprintf formats is a backslash and an n on the controller: its log is one
    line the reader refuses, as the project's old test could not see (it replaced them before reading)."""
    old = ROOT / "tests" / "data" / "robot" / "old"
    src, dat = (old / "StiffCompProbe.src").read_text(), (old / "StiffCompProbe.dat").read_text()
    text = krl_log(src, krl_data(dat), [(Q[0], 1.0, 0.0)])
    assert "\n" not in text and "\\n" in text
    assert log_mismatches(text, "old") != []


@pytest.mark.parametrize("name, value", [("nTouches", 36), ("rStylus", 2.0), ("vProbe", 10.0), ("latencyMs", 0.5),
                                         ("rPath", 40.0), ("depth", 3.0)])
def test_a_plan_that_drifts_is_named_in_both(name, value):
    want, xyz, rpy, src, dat, mod = shipped()
    want = {**want, name: value}
    assert any(m.startswith(f"{name} ") for m in krl_mismatches(want, xyz, rpy, src, dat))
    assert any(m.startswith(f"{name} ") for m in rapid_mismatches(want, xyz, rpy, mod))


def test_a_file_that_drifts_is_named():
    want, xyz, rpy, src, dat, mod = shipped()
    assert any("rStylus" in m for m in krl_mismatches(want, xyz, rpy, src, dat.replace("rStylus=1.5", "rStylus=2.0")))
    assert any("$MEAS_PULSE" in m for m in krl_mismatches(want, xyz, rpy, src.replace("$MEAS_PULSE[1]", "$IN[1]"), dat))
    assert any("$AXIS_INT" in m for m in krl_mismatches(want, xyz, rpy, src.replace("$AXIS_INT", "$AXIS_ACT"), dat))
    assert any("probing speed" in m for m in krl_mismatches(want, xyz, rpy, src.replace("vProbe / 1000.0", "0.05"), dat))
    assert any("probeFrame" in m for m in krl_mismatches(want, xyz, rpy, src, dat.replace("Z 250.0", "Z 260.0")))
    assert any("header row" in m for m in krl_mismatches(want, xyz, rpy, src.replace("q6_deg,approach", "q6,approach"), dat))
    assert any("refuses" in m for m in krl_mismatches(want, xyz, rpy, src.replace("# trigger_latency_ms", "# latency"), dat))
    assert any("vSearch" in m for m in rapid_mismatches(want, xyz, rpy, mod.replace("[5, 500, 5000, 1000]", "[50, 500, 5000, 1000]")))
    assert any("CalcJointT" in m for m in rapid_mismatches(want, xyz, rpy, mod.replace("CalcJointT(pHit", "CalcJointT(pEnd")))
    assert any("stylus_radius_mm" in m for m in rapid_mismatches(want, xyz, rpy, mod.replace('"# stylus_radius_mm: "', '"# stylus: "')))
    assert any("PROBE_XYZ" in m for m in rapid_mismatches(want, xyz, rpy, mod.replace("[0, 0, 250]", "[0, 0, 255]")))
