"""Every robot-side program the product ships (robot/), written from its plan: the probe programs from the HIL
scenario's probe plan and the robot's tcp, the KUKA RSI files from a config whose ``robot.interface`` is kuka_rsi,
the ABB EGM files from one whose interface is abb_egm. ``stiffcomp robot-programs`` writes them; the committed
files in robot/ are this output (tests/cell/test_robot_programs.py holds them byte-equal)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from service.config import load_config
from stiffness.errors import ConfigError

from . import egm, probe_krl, probe_rapid, rsi
from .plan import CONFIGS, ROBOT, SCENARIO, load_probe_plan


@dataclass
class Programs:
    """The files (relative path -> text) and what the configs must change for them (one line each)."""

    files: dict[str, str] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


def _max_correction(value) -> float:
    return float(max(value)) if isinstance(value, (list, tuple)) else float(value)


def generate(configs: tuple[Path, ...] = CONFIGS, scenario: Path = SCENARIO, robot: Path = ROBOT) -> Programs:
    """The programs for ``configs`` (each a service config with a robot interface) and the probe plan."""
    plan = load_probe_plan(scenario, robot)
    out = Programs({"probe/StiffCompProbe.src": probe_krl.probe_src(), "probe/StiffCompProbe.dat": probe_krl.probe_dat(plan),
                    "probe/StiffCompProbe.modx": probe_rapid.probe_modx(plan)})
    seen = set()
    for path in configs:
        cfg = load_config(path)
        r = cfg.robot
        if r.interface in seen or r.interface == "none":
            raise ConfigError(f"{path}: robot.interface {r.interface}: give one config for each of kuka_rsi and "
                              "abb_egm")
        seen.add(r.interface)
        if r.interface == "kuka_rsi":
            out.files["kuka_rsi/StiffCompCut.src"] = rsi.cut_src(r)
            out.files["kuka_rsi/StiffComp.xml"] = rsi.ethernet_xml(r)
            out.notes += [f"{path}: {n}" for n in rsi.config_notes(r)]
        else:
            out.files["abb_egm/StiffCompEgm.modx"] = egm.egm_modx(
                r, _max_correction(cfg.limits.max_correction_deg), cfg.faults.plc_heartbeat_timeout_ms)
            out.files["abb_egm/StiffCompMoc.cfg"] = egm.moc_cfg()
            out.files["abb_egm/StiffCompUdpuc.cfg"] = egm.udpuc_cfg(r)
    return out
