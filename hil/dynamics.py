"""The dynamic compensation in the HIL (`stiffcomp hil circle --dynamic-compensation`, docs/dynamics.md).

What a commissioning engineer does, with the HIL's instruments:

1. record a force and a path: the process force at the tool and the robot stub's deflection from its path
   on the uncompensated pass, every millisecond (a dynamometer and a laser tracker on a test cut; written
   with ``--modes-data`` in the format `stiffcomp modes` reads);
2. identify the structure's modes from it (`stiffness.dynamics.identify`, as `stiffcomp modes` does);
3. measure the end-to-end delay with the static compensator (the run's static pass, `hil.report.end_to_end_delay`);
4. give the service the modes (their frequencies scaled by 1 + ``mode_error``: a model that is off), the
   delay, and with ``feedforward`` the process plan (`write_plan`: the engagement and the force the milling
   model plans, over the PLC program's time, which the virtual PLC writes to ``plan_time_s``).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plc_interface.endpoints import SHIPPED_CONFIG
from stiffness.dynamics.identify import DEFLECTION, FORCE, Identified, Record, identify
from stiffness.model import StiffnessModel
from stiffness.units import M_TO_MM
from stiffness.yamlio import dump_yaml, read_yaml

from .report import evaluate_uncompensated
from .robot_stub import RobotStub
from .scenario import Scenario
from .world import World

RECORD_PERIOD_S = 0.001
PLAN_REGISTERS = ({"name": "plan_time_s", "address": 0x800F, "type": "float32", "unit": "s"},      # no gap: a PLC writes its block whole
                  {"name": "plan_engagement", "address": 0x8011, "type": "float32"})


@dataclass
class DynamicOptions:
    """``--dynamic-compensation`` and its variants."""

    mode_error: float = 0.0          # the service's mode frequencies scaled by 1 + mode_error
    added_damping: float = 0.0       # dynamics.structure.added_damping
    feedforward: bool = False        # the process plan too
    n_modes: int = 2
    record: Path | None = None       # write the commissioning record here (stiffcomp modes reads it)
    predictor: bool = True


def commissioning_record(scenario: Scenario, truth: StiffnessModel) -> Record:
    """The process force at the tool and the stub's TCP deflection from its path (uncompensated), every ms."""
    world = World(scenario, truth.robot)
    stub = RobotStub(truth, scenario.robot, scenario.payload)
    ev = evaluate_uncompensated(world, stub, RECORD_PERIOD_S)
    q = np.array([world.path.q_ref_deg(x) for x in ev["t"]])
    nominal = truth.robot.frames(np.radians(q))[:, 7, :3, 3]
    return Record(ev["t"] - ev["t"][0], world.force(ev["t"]), ev["p"] - nominal, "the HIL's uncompensated pass")


def write_record(rec: Record, path: Path) -> None:
    """The record as `stiffcomp modes` reads it (t_s, fx_N .. fz_N, dx_mm .. dz_mm)."""
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", *FORCE, *DEFLECTION])
        for t, F, d in zip(rec.t, rec.force, rec.deflection * M_TO_MM):
            w.writerow([f"{t:.4f}", *(f"{x:.3f}" for x in F), *(f"{x:.6f}" for x in d)])


def write_plan(world: World, path: Path) -> None:
    """The process plan over the PLC program's time: t_s, engagement, fx_N, fy_N, fz_N (docs/dynamics.md)."""
    t = np.arange(world.t_start, world.t_end, RECORD_PERIOD_S)
    F = world.planned_force(t)
    e = world.milling.engagement(t)
    with open(path, "w", newline="") as f:
        w = csv.writer(f)
        w.writerow(["t_s", "engagement", "fx_N", "fy_N", "fz_N"])
        for row in zip(world.program_time(t), e, *F.T):
            w.writerow([f"{row[0]:.4f}", f"{row[1]:.5f}", *(f"{x:.2f}" for x in row[2:])])


def plan_register_map(source: Path, folder: Path) -> Path:
    """The register map ``source`` with the plan's two values added (docs/register_map.md, "The plan")."""
    data = read_yaml(source)
    data["from_plc"]["registers"] += [dict(r) for r in PLAN_REGISTERS]
    path = folder / "registers_plan.yaml"
    path.write_text(dump_yaml(data, sort_keys=False))
    return path


def service_dynamics(found: Identified, delay_ms: float, opts: DynamicOptions, scenario: Scenario,
                     world: World, folder: Path) -> dict:
    """The service config's overrides: ``dynamics`` with the identified modes (scaled by 1 + mode_error), the
    measured delay and, with the feedforward, the plan and a register map that carries it."""
    section = {"enabled": True, "delay_ms": round(delay_ms, 2), "structure": structure_section(found, opts)}
    if opts.predictor:
        section["predictor"] = {}
    out = {"dynamics": section}
    if opts.feedforward:
        folder.mkdir(parents=True, exist_ok=True)
        write_plan(world, folder / "plan.csv")
        section["feedforward"] = {"source": "file", "file": str(folder / "plan.csv"),
                                  "output_delay_ms": scenario.plc.period_ms / 2 + scenario.plc.extra_delay_ms}
        out["plc"] = {"register_map": str(plan_register_map(SHIPPED_CONFIG / "registers.yaml", folder))}
    return out


def structure_section(found: Identified, opts: DynamicOptions) -> dict:
    """``dynamics.structure`` of the identified modes, their frequencies scaled by 1 + ``opts.mode_error``."""
    structure = found.to_config()
    for m in structure["modes"]:
        m["hz"] = round(m["hz"] * (1.0 + opts.mode_error), 3)
    structure["added_damping"] = opts.added_damping
    return structure


def identify_from_pass(scenario: Scenario, truth: StiffnessModel, opts: DynamicOptions) -> Identified:
    """Steps 1 and 2: the record (written to ``opts.record`` when given) and the modes found in it."""
    rec = commissioning_record(scenario, truth)
    if opts.record is not None:
        write_record(rec, Path(opts.record))
    return identify(rec, opts.n_modes)
