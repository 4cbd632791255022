"""Helpers of the HIL tests: scenarios, models written for the service, one compensated pass."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hil.device_log import PlcLog
from hil.lockstep import run_lockstep
from hil.report import Evaluation, errors, evaluate_pass
from hil.run import Faults, PassResult, run_pass
from hil.scenario import ROOT, Scenario, load_scenario
from plc_link.register_map import RegisterMap
from stiffness.model.stiffness_model import StiffnessModel

EXAMPLES = ROOT / "examples"
MODELS = ROOT / "config" / "models"
RMAP = RegisterMap.from_yaml(ROOT / "config" / "registers.yaml")
OUT = RMAP.codecs["to_plc"].names
FROM_PLC = {a for r in RMAP.registers if r.direction == "from_plc" for a in range(r.address, r.address + r.count)}


def scenario(feed_mm_s: float | None = None, center_q_deg: list[float] | None = None) -> Scenario:
    """config/hil/circle.yaml, with another feed or another pose at the circle's centre."""
    sc = load_scenario()
    if feed_mm_s is not None:
        sc.circle.feed_mm_s = feed_mm_s
    if center_q_deg is not None:
        sc.circle.center_q_deg = list(center_q_deg)
    return sc


def write_model(model: StiffnessModel, path: Path) -> Path:
    """The model as YAML at ``path`` (its robot referred to from there); ``path``."""
    model.to_yaml(path)
    return path


def compensated(sc: Scenario, truth: Path, model: Path, folder: Path, faults: Faults | None = None,
                compensate: bool = True, lockstep: bool = False) -> tuple[PassResult, Evaluation]:
    """One pass and its evaluation (actual TCP, radial error): in real time (the service's processes, the
    sensor's and the PLC's), or in lock step (`hil.lockstep`: the service's own cycle stepped with the virtual
    sensor and PLC in this process, a second or two instead of three process start-ups and the pass's length;
    the same figures on a busy host), where what a test holds is the model's, not real time's."""
    t = StiffnessModel.from_yaml(truth)
    if lockstep:
        if faults is not None:
            raise ValueError("faults are injected into the real-time run's processes: lockstep=False")
        r = run_lockstep(sc, t, model, compensate, folder)
    else:
        r = run_pass(sc, t, model, compensate, folder, faults)
    return r, evaluate_pass(sc, t, r)[1]


def mean_error(ev: Evaluation, t_from: float = -np.inf, t_to: float = np.inf) -> float:
    m = ev.cut & (ev.t >= t_from) & (ev.t < t_to)
    return float(np.abs(ev.err_mm[m]).mean()) if m.any() else float("nan")


def plc_log(r: PassResult) -> PlcLog:
    """The log of a pass the virtual PLC ran; TypeError for a pass through the robot road."""
    if not isinstance(r.log, PlcLog):
        raise TypeError(f"the pass ran the virtual {r.log.device}, not the PLC: it has no PLC log")
    return r.log


def value(r: PassResult, name: str) -> np.ndarray:
    """A to_plc value per PLC cycle as the PLC read it (NaN where the read failed)."""
    return plc_log(r).to_plc[:, OUT.index(name)]


def corrections(r: PassResult) -> np.ndarray:
    return plc_log(r).to_plc[:, [OUT.index(f"correction_q{i}") for i in range(1, 7)]]


def nothing_outside_the_map(r: PassResult) -> list[str]:
    """Problems: the PLC wrote outside its registers, a word outside the map is nonzero, a write was refused."""
    problems = [f"PLC wrote {a:#06x}" for a in plc_log(r).written if int(a) not in FROM_PLC]
    problems += r.extra["unmapped_nonzero"]
    problems += [line for line in r.service_log.splitlines() if "refused a write" in line]
    return problems


__all__ = ["EXAMPLES", "MODELS", "ROOT", "Faults", "errors"]
