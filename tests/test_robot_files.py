"""The robot-side files in robot/ (what an integrator loads into a KUKA or ABB controller) are held to the
shipped service configs that answer them, and docs/robot.md and docs/config.md to the `robot` schema.

`kuka_mismatches` and `abb_mismatches` list every value that differs between a config's ``robot`` section and
the files; the shipped pair must give none, and a copy drifted in one value must name that value.
"""

from __future__ import annotations

import re
from pathlib import Path

import defusedxml.ElementTree as DET
import pytest
import yaml
from pydantic import BaseModel

from robot_road import registry
from robot_road.settings import RobotSettings
from service.config import load_config
from testlib.common import ROOT

KUKA, ABB = ROOT / "cell" / "robot" / "generated" / "kuka_rsi", ROOT / "cell" / "robot" / "generated" / "abb_egm"
CONFIGS = {"kuka_rsi": ROOT / "config" / "robot_kuka_rsi.yaml", "abb_egm": ROOT / "config" / "robot_abb_egm.yaml"}
AXES, CARTESIAN = [f"AK.A{i}" for i in range(1, 7)], [f"RKorr.{c}" for c in "XYZABC"]
SENSOR_MODE = {4: "IPO_FAST", 12: "IPO"}


def robot_section(path: Path) -> RobotSettings:
    return RobotSettings.model_validate(yaml.safe_load(path.read_text())["robot"])


def drift(r: RobotSettings, **changes) -> RobotSettings:
    """``r`` with some keys changed; ``kuka_rsi__cartesian=True`` reaches into a sub-section."""
    top = {k: v for k, v in changes.items() if "__" not in k}
    for key, value in changes.items():
        if "__" in key:
            sub, name = key.split("__")
            top[sub] = top.get(sub, getattr(r, sub)).model_copy(update={name: value})
    return r.model_copy(update=top)


# -- KUKA RSI ---------------------------------------------------------------------------------------------
def krl_code(text: str) -> str:
    """A KRL program without its comments (``;`` to the end of the line)."""
    return "\n".join(line.split(";", 1)[0] for line in text.splitlines())


def kuka_mismatches(r: RobotSettings, xml_text: str, krl_text: str) -> list[str]:
    """Each value of StiffComp.xml and StiffCompCut.src that differs from the config's ``robot`` section."""
    k, out = r.kuka_rsi, []
    root = DET.fromstring(xml_text, forbid_dtd=True)
    cfg = root.find("CONFIG")
    for tag, want, key in (("IP_NUMBER", r.host, "robot.host"), ("PORT", str(r.port), "robot.port"),
                           ("SENTYPE", k.sen_type, "robot.kuka_rsi.sen_type"), ("ONLYSEND", "FALSE", "answers")):
        got = (cfg.findtext(tag) or "").strip()
        if got != want:
            out.append(f"{tag} {got!r} but {key} wants {want!r}")
    sent = {e.get("TAG"): e.get("INDX") for e in root.iterfind("SEND/ELEMENTS/ELEMENT")}
    for tag in (f"DEF_{k.joints}", "DEF_Delay"):
        if sent.get(tag) != "INTERNAL":
            out.append(f"SEND lacks {tag} (robot.kuka_rsi.joints {k.joints}, the late count)")
    for name in ("command", "heartbeat", "payload"):
        tag = getattr(k, f"{name}_element")
        if tag is not None and not (sent.get(tag) or "INTERNAL").isdigit():
            out.append(f"SEND lacks a numbered element {tag} (robot.kuka_rsi.{name}_element)")
    received = list(root.iterfind("RECEIVE/ELEMENTS/ELEMENT"))
    want_tags = CARTESIAN if k.cartesian else AXES
    if [e.get("TAG") for e in received] != want_tags:
        out.append(f"RECEIVE {[e.get('TAG') for e in received]} but robot.kuka_rsi.cartesian {k.cartesian} "
                   f"wants {want_tags}")
    holdon = "1" if k.correction == "absolute" else "0"
    if any(e.get("HOLDON") != holdon for e in received):
        out.append(f"RECEIVE HOLDON is not {holdon} for robot.kuka_rsi.correction {k.correction}")
    calls = re.findall(r"RSI_ON\s*\(\s*#(\w+)\s*(?:,\s*#(\w+)\s*)?\)", krl_code(krl_text))
    if len(calls) != 1:
        out.append(f"{len(calls)} RSI_ON calls in the KRL program, not one")
    for mode, sensor in calls:
        if mode != k.correction.upper():
            out.append(f"RSI_ON(#{mode}) but robot.kuka_rsi.correction is {k.correction}")
        if (sensor or "IPO_FAST") != SENSOR_MODE[k.cycle_ms]:
            out.append(f"RSI_ON's #{sensor or 'IPO_FAST'} but robot.kuka_rsi.cycle_ms is {k.cycle_ms}")
    return out


def kuka_shipped() -> tuple[RobotSettings, str, str]:
    """The shipped KUKA config as the cut needs it (its RSI cycle 12 ms: KUKA.RSI corrects programmed motions only
    in #IPO, docs/robot.md "Which sensor mode") and the shipped files."""
    return (drift(robot_section(CONFIGS["kuka_rsi"]), kuka_rsi__cycle_ms=12), (KUKA / "StiffComp.xml").read_text(),
            (KUKA / "StiffCompCut.src").read_text())


def test_the_kuka_files_match_the_shipped_config():
    r, xml_text, krl_text = kuka_shipped()
    assert r.interface == "kuka_rsi"
    assert kuka_mismatches(r, xml_text, krl_text) == []


def test_the_shipped_kuka_config_says_the_cuts_12_ms():
    _, xml_text, krl_text = kuka_shipped()
    assert kuka_mismatches(robot_section(CONFIGS["kuka_rsi"]), xml_text, krl_text) == []


@pytest.mark.parametrize("changes, named", [
    ({"port": 49153}, "PORT"),
    ({"host": "192.168.1.11"}, "IP_NUMBER"),
    ({"kuka_rsi__sen_type": "Other"}, "SENTYPE"),
    ({"kuka_rsi__cartesian": True}, "RKorr.X"),
    ({"kuka_rsi__correction": "relative"}, "HOLDON"),
    ({"kuka_rsi__correction": "relative"}, "RSI_ON(#ABSOLUTE)"),
    ({"kuka_rsi__cycle_ms": 4}, "RSI_ON's #IPO but robot.kuka_rsi.cycle_ms is 4"),
    ({"kuka_rsi__command_element": "StiffCmd"}, "StiffCmd"),
])
def test_a_kuka_config_that_drifts_is_named(changes, named):
    r, xml_text, krl_text = kuka_shipped()
    found = kuka_mismatches(drift(r, **changes), xml_text, krl_text)
    assert any(named in m for m in found), found


def test_a_kuka_file_that_drifts_is_named():
    r, xml_text, krl_text = kuka_shipped()
    assert any("SENTYPE" in m for m in kuka_mismatches(r, xml_text.replace("ImFree", "ImFixed"), krl_text))
    assert any("PORT" in m for m in kuka_mismatches(r, xml_text.replace("49152", "49160"), krl_text))
    assert any("HOLDON" in m for m in kuka_mismatches(r, xml_text.replace('HOLDON="1"', 'HOLDON="0"'), krl_text))
    no_setpoints = re.sub(r'<ELEMENT TAG="DEF_ASPos"[^>]*>', "", xml_text)
    assert any("DEF_ASPos" in m for m in kuka_mismatches(r, no_setpoints, krl_text))
    relative = krl_text.replace("RSI_ON(#ABSOLUTE", "RSI_ON(#RELATIVE")
    assert any("RSI_ON(#RELATIVE)" in m for m in kuka_mismatches(r, xml_text, relative))


def test_the_commented_command_element_works_once_uncommented():
    r, xml_text, krl_text = kuka_shipped()
    line = '<ELEMENT TAG="StiffCmd" TYPE="LONG" INDX="1" />'
    assert xml_text.count(line) == 1 and DET.fromstring(xml_text).find(".//ELEMENT[@TAG='StiffCmd']") is None
    uncommented = xml_text.replace(line, "-->" + line + "<!--")
    assert kuka_mismatches(drift(r, kuka_rsi__command_element="StiffCmd"), uncommented, krl_text) == []


# -- ABB EGM ----------------------------------------------------------------------------------------------
def cfg_instances(text: str, type_name: str) -> list[dict[str, str]]:
    """The instances of one type of an ABB .cfg file (``-Key value`` pairs; a flag without a value is "")."""
    text = re.sub(r"\\\s*\n\s*", " ", text)                     # a line ending in \ goes on on the next
    out, current = [], None
    for line in text.splitlines():
        if line.startswith("#") or not line.strip():
            continue
        if re.match(r"^\w+:\s*$", line):
            current = line.strip()[:-1]
        elif current == type_name and line.strip().startswith("-"):
            pairs = re.findall(r'-(\w+)(?:\s+("[^"]*"|(?!-)\S+))?', line)
            out.append({key: value.strip('"') for key, value in pairs})
    return out


def rapid_code(text: str) -> tuple[str, dict[str, str]]:
    """A RAPID module without its comments (``!`` to the end of the line, outside strings), and its CONSTs."""
    code = "\n".join(re.sub(r'^((?:[^"!]|"[^"]*")*)!.*$', r"\1", line) for line in text.splitlines())
    consts = dict(re.findall(r"CONST\s+(?:string|num)\s+(\w+)\s*:=\s*\"?([^\";]*)\"?\s*;", code))
    return code, consts


def abb_mismatches(r: RobotSettings, sio_text: str, moc_text: str, rapid_text: str) -> list[str]:
    """Each value of the UDP unit, the motion profiles and the RAPID module that differs from the config."""
    out = []
    units = [u for u in cfg_instances(sio_text, "COM_TRP") if u.get("Type") == "UDPUC"]
    if len(units) != 1:
        return [f"{len(units)} UDPUC units in the SIO.cfg fragment, not one"]
    unit = units[0]
    for key, want, name in (("RemoteAdress", r.host, "robot.host"), ("RemotePortNumber", str(r.port), "robot.port")):
        if unit.get(key) != want:
            out.append(f"{key} {unit.get(key)!r} but {name} wants {want!r}")
    levels = {p["name"]: p.get("ext_motion_level") for p in cfg_instances(moc_text, "EXT_MOTION_DATA")}
    code, consts = rapid_code(rapid_text)

    def value(arg: str) -> str:                                 # a CONST's value, or the literal itself
        return consts.get(arg, arg.strip('"'))

    setups = re.findall(r"EGMSetupUC\s+ROB_1\s*,\s*\w+\s*,\s*(\S+?)\s*,\s*(\S+?)\s*\\(\w+)", code)
    for profile, device, switch in setups:
        if value(device) != unit.get("Name"):
            out.append(f"EGMSetupUC names the unit {value(device)!r}, the SIO.cfg fragment defines {unit.get('Name')!r}")
        if value(profile) not in levels:
            out.append(f"EGMSetupUC's profile {value(profile)!r} is not in the MOC.cfg fragment")
        elif switch == "PathCorr" and levels[value(profile)] != "2":
            out.append(f"EGMSetupUC's PathCorr profile {value(profile)!r} is at level {levels[value(profile)]}, "
                       "not 2 (path)")
    mode = {"path": ("PathCorr", "EGMActMove"), "joint": ("Joint", "EGMActJoint")}[r.abb_egm.mode]
    if mode[0] not in {s for _, _, s in setups}:
        out.append(f"no EGMSetupUC \\{mode[0]} for robot.abb_egm.mode {r.abb_egm.mode}")
    rates = [value(v) for v in re.findall(rf"{mode[1]}\b[^;]*\\SampleRate:=(\w+)", code)]
    if rates != [str(r.abb_egm.cycle_ms)]:
        out.append(f"{mode[1]}'s \\SampleRate {rates} but robot.abb_egm.cycle_ms is {r.abb_egm.cycle_ms}")
    return out


def abb_shipped() -> tuple[RobotSettings, str, str, str]:
    return (robot_section(CONFIGS["abb_egm"]), (ABB / "StiffCompUdpuc.cfg").read_text(),
            (ABB / "StiffCompMoc.cfg").read_text(), (ABB / "StiffCompEgm.modx").read_text())


def test_the_abb_files_match_the_shipped_config():
    r, *files = abb_shipped()
    assert r.interface == "abb_egm" and r.abb_egm.mode == "path"
    assert abb_mismatches(r, *files) == []
    # the module's joint mode matches the same config switched to joint mode at its 4 ms
    assert abb_mismatches(drift(r, abb_egm__mode="joint", abb_egm__cycle_ms=4), *files) == []


@pytest.mark.parametrize("changes, named", [
    ({"port": 6510}, "RemotePortNumber"),
    ({"host": "192.168.10.21"}, "RemoteAdress"),
    ({"abb_egm__cycle_ms": 24}, "SampleRate"),
    ({"abb_egm__mode": "joint"}, "EGMActJoint's \\SampleRate ['4'] but robot.abb_egm.cycle_ms is 48"),
])
def test_an_abb_config_that_drifts_is_named(changes, named):
    r, *files = abb_shipped()
    found = abb_mismatches(drift(r, **changes), *files)
    assert any(named in m for m in found), found


def test_an_abb_file_that_drifts_is_named():
    r, sio, moc, rapid = abb_shipped()
    assert any("names the unit" in m for m in abb_mismatches(r, sio.replace('"StiffComp"', '"EGMsensor"'), moc, rapid))
    assert any("RemotePortNumber" in m for m in abb_mismatches(r, sio.replace("6511", "6512"), moc, rapid))
    assert any("PathCorr profile" in m for m in abb_mismatches(r, sio, moc.replace("level 2", "level 1"), rapid))
    rate = rapid.replace("PATH_SAMPLE_MS := 48", "PATH_SAMPLE_MS := 72")
    assert any("SampleRate ['72']" in m for m in abb_mismatches(r, sio, moc, rate))


def test_the_cfg_reader_joins_continued_lines_and_keeps_flags():
    text = 'MOC:CFG_1.0::\n#\nEXT_MOTION_DATA:\n\n  -name "a" -flag\\\n    -level 2\n  -name "b"\n'
    assert cfg_instances(text, "EXT_MOTION_DATA") == [{"name": "a", "flag": "", "level": "2"}, {"name": "b"}]


def test_the_virtual_abb_robot_filters_as_the_shipped_joint_profile():
    """hil.virtual_abb's position guidance (gain and filter bandwidth) is the shipped StiffCompMoc.cfg's
    StiffCompJoint profile, so the HIL's joint mode is what the shipped robot side does."""
    from hil import virtual_abb

    joint = {p["name"]: p for p in cfg_instances((ABB / "StiffCompMoc.cfg").read_text(), "EXT_MOTION_DATA")}
    joint = joint["StiffCompJoint"]
    assert float(joint["ext_motion_Kp"]) == virtual_abb.KP
    assert float(joint["ext_motion_filter_bandwidth"]) == virtual_abb.BANDWIDTH_HZ


# -- the configs as the service loads them ----------------------------------------------------------------
@pytest.mark.parametrize("interface", sorted(CONFIGS))
def test_the_robot_configs_load_and_differ_from_default_only_in_plc_and_robot(interface):
    path = CONFIGS[interface]
    cfg = load_config(path)
    assert cfg.robot.interface == interface and cfg.plc.role == "none" and cfg.plc.enable_on_start
    assert cfg.robot.peer is not None and cfg.robot.exposure_warning() is None
    ours, default = yaml.safe_load(path.read_text()), yaml.safe_load((ROOT / "config" / "default.yaml").read_text())
    assert {k: v for k, v in ours.items() if k not in ("plc", "robot")} == \
        {k: v for k, v in default.items() if k not in ("plc", "robot")}


# -- the docs ---------------------------------------------------------------------------------------------
def leaf_defaults(model: type[BaseModel] | None = None, prefix: str = "") -> dict[str, object]:
    """Every leaf key of the ``robot`` schema (dotted below ``robot``) and its default: the section's own fields and
    each built-in interface's sub-section (the ones the docs document)."""
    if model is None:
        out = leaf_defaults(RobotSettings)
        for name in registry.BUILT_IN:
            out |= leaf_defaults(registry.declared(name).settings, f"{name}.")
        return out
    out = {}
    for name, field in model.model_fields.items():
        sub = field.annotation if isinstance(field.annotation, type) and issubclass(field.annotation, BaseModel) \
            else None
        out |= leaf_defaults(sub, f"{prefix}{name}.") if sub else {prefix + name: field.default}
    return out


def test_every_robot_key_docs_robot_md_names_exists():
    text = (ROOT / "docs" / "robot.md").read_text()
    named = set(re.findall(r"`robot\.([a-z_]+(?:\.[a-z_]+)*)", text))
    assert len(named) >= 10
    assert sorted(named - set(leaf_defaults())) == []


def shown(value) -> str:
    """A default as docs/config.md writes it (YAML's null, true, false)."""
    return "null" if value is None else str(value).lower() if isinstance(value, bool) else str(value)


def test_docs_config_md_gives_each_robot_key_its_default():
    text = (ROOT / "docs" / "config.md").read_text()
    section = text[text.index("## `robot`"):]
    rows = dict(re.findall(r"^\| `([a-z_.]+)` \| ([^|]+?) \|", section, re.MULTILINE))
    assert rows == {k: shown(v) for k, v in leaf_defaults().items()}


# -- the files as the controllers' parsers read them ----------------------------------------------------------
def test_the_rsi_xml_has_only_one_line_comments():
    """Field-proven RSI configurations comment one line at a time; an element commented out inside a longer
    comment is what a controller's parser may not skip."""
    text = (KUKA / "StiffComp.xml").read_text()
    for line in text.splitlines():
        assert line.count("<!--") == line.count("-->"), line
    assert text.count('<!-- <ELEMENT TAG="StiffCmd" TYPE="LONG" INDX="1" /> -->') == 1


@pytest.mark.parametrize("name, domain", [("StiffCompMoc.cfg", "MOC"), ("StiffCompUdpuc.cfg", "SIO")])
def test_the_abb_cfg_headers_carry_their_version(name, domain):
    """A .cfg file as RobotStudio saves it starts with ``DOMAIN:CFG_1.0:<major>:<minor>::``."""
    first = (ABB / name).read_text().splitlines()[0]
    assert re.fullmatch(rf"{domain}:CFG_1\.0:\d+:\d+::", first), first


# The attributes controllers save, in their order: a UDPUC unit in SIO.cfg's COM_TRP (SYSPAR/SIO.cfg of
# panin-anan/abb_SAMXL_Grinding_RAPID and joseballester/abb-rapidserver) and an EGM profile in MOC.cfg's
# EXT_MOTION_DATA (rpiRobotics/abb_motion_program_exec, robot/config_params_egm/MOC.cfg).
SAVED_UDPUC = ["Name", "Type", "PhyChannel", "RemoteAdress", "RemotePortNumber"]
SAVED_PROFILE = {"name", "ext_motion_level", "do_not_restart_after_motors_off", "ramp_time", "ext_motion_Kp",
                 "ext_motion_filter_bandwidth"}


def test_the_abb_cfg_fragments_spell_their_attributes_as_controllers_save_them():
    """No attribute a saved file does not have (a misspelt one is dropped by the controller's loader without a
    word): the UDP unit with exactly the saved attributes in the saved order, each profile a subset of a saved
    profile's, with an integer level."""
    (unit,) = cfg_instances((ABB / "StiffCompUdpuc.cfg").read_text(), "COM_TRP")
    assert list(unit) == SAVED_UDPUC and unit["Type"] == "UDPUC" and unit["PhyChannel"] == ""
    profiles = cfg_instances((ABB / "StiffCompMoc.cfg").read_text(), "EXT_MOTION_DATA")
    assert len(profiles) == 2
    for profile in profiles:
        assert set(profile) <= SAVED_PROFILE, set(profile) - SAVED_PROFILE
        assert profile["ext_motion_level"] in {"0", "1", "2"}


@pytest.mark.parametrize("interface", sorted(CONFIGS))
def test_the_robot_port_is_exposed_and_documented_where_the_others_are(interface):
    """The shipped robot config's UDP port is in the Dockerfile's EXPOSE, docs/deploy.md's ports table, its
    bridge -p line and its Kubernetes example (RSI's as the port, EGM's in the comment beside it)."""
    port = robot_section(CONFIGS[interface]).port
    expose = next(line for line in (ROOT / "Dockerfile").read_text().splitlines() if line.startswith("EXPOSE"))
    assert f"{port}/udp" in expose.split()
    deploy = (ROOT / "docs" / "deploy.md").read_text()
    assert re.search(rf"^\| [^|]*\b{port}/udp\b", deploy, re.MULTILINE) and f"-p {port}:{port}/udp" in deploy
    assert f"{{name: robot, containerPort: {port}, protocol: UDP}}" in deploy


def test_the_docs_agree_on_the_virtual_robots_timeout_and_rkorrs_frame():
    """docs/robot.md and docs/hil.md give the HIL's virtual robot the timeout it has; RKorr is the robot's root
    frame (POSCORR's RefCorrSys RobRoot), not $BASE, which the shipped KRL sets to the part's."""
    from hil.virtual_robot import TIMEOUT_COUNT

    robot_md, hil_md = ((ROOT / "docs" / n).read_text() for n in ("robot.md", "hil.md"))
    assert f"stops after {TIMEOUT_COUNT} late answers in a row" in robot_md
    assert f"stops after {TIMEOUT_COUNT} late in a row" in hil_md
    assert "`RefCorrSys` RobRoot" in robot_md and "`RefCorrSys` Base;" not in robot_md
    assert "$BASE = BASE_DATA" in (KUKA / "StiffCompCut.src").read_text()
