"""The dynamic compensation in the HIL (`stiffcomp hil circle --dynamic-compensation`, docs/dynamics.md).

What a commissioning engineer does, with the HIL's instruments:

1. record a force and a path, every millisecond, in the format `stiffcomp modes` reads (``--modes-data``):
   a tap test at the circle's centre (``tap``, the default: an impulse hammer's force along x, y and z in
   turn and the robot stub's deflection, as an accelerometer or a laser tracker records it, 1 µm noise), or
   the uncompensated test cut itself (``cut``: the process force and the stub's deflection from its path);
   a tap test moves the joints too little to cross their hysteresis or play, so it sees the structure alone;
2. identify the structure's modes from it (`stiffness.dynamics.modes`, as `stiffcomp modes` does);
3. measure the end-to-end delay with the static compensator (the run's static pass, `hil.report.end_to_end_delay`);
4. give the service the modes (their frequencies scaled by 1 + ``mode_error``: a model that is off), the
   delay, and with ``feedforward`` the process plan (`write_plan`: the engagement and the force the milling
   model plans, over the PLC program's time, which the virtual PLC writes to ``plan_time_s``).

With ``modes_file`` step 1 and 2 are a file's modes instead (what `stiffcomp modes -o` writes, e.g. from a
cut's trace: docs/accelerometer.md); with ``observer`` the service also runs the accelerometer's observer, and
every pass measures with the virtual box (`DynamicOptions.measured_by`).
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from plc_link.register_map import RegisterMap
from service.config import load_config
from stiffness.dynamics.modes import DEFLECTION, FORCE, Identified, Record, identify
from stiffness.files.yaml_schema import dump_yaml
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.units import M_TO_MM

from .device_log import Track
from .report import Evaluation, end_to_end_delay, errors, evaluate_pass, evaluate_uncompensated, window_errors
from .robot_stub import RobotStub
from .run import HilError
from .scenario import Scenario
from .world import World

RECORD_PERIOD_S = 0.001
TAP_N, TAP_MS, TAP_EVERY_S, TAP_NOISE_M = 100.0, 3.0, 1.2, 1e-6     # the hammer: peak force, pulse, spacing
PLAN_VALUES = ("plan_time_s", "plan_engagement")


@dataclass
class DynamicOptions:
    """``--dynamic-compensation`` and its variants."""

    mode_error: float = 0.0          # the service's mode frequencies scaled by 1 + mode_error
    added_damping: float = 0.0       # dynamics.structure.added_damping
    feedforward: bool = False        # the process plan too
    n_modes: int = 2
    record: Path | None = None       # write the commissioning record here (stiffcomp modes reads it)
    commissioning: str = "tap"       # tap | cut: the record (module docstring)
    predictor: bool = True
    predictor_hz: float | None = None    # dynamics.predictor.bandwidth_hz (None: its default)
    delay_ms: float | None = None        # dynamics.delay_ms (None: measured on the static pass, `service_delay_ms`)
    observer: bool = False               # the accelerometer at the tool and dynamics.observer with the modes
    observer_horizon_ms: float | None = None     # dynamics.observer.horizon_ms (None: `observer_horizon_ms`)
    observer_band_hz: tuple[float, float] | None = None     # dynamics.observer.band_hz (None: its default)
    follow: bool = False                 # dynamics.observer.follow: the modes followed in the cut
    modes_file: Path | None = None       # the modes (and lag) of this file's dynamics.structure, not the tap test's

    def measured_by(self, scenario: Scenario) -> Scenario:
        """``scenario`` with the accelerometer on where the observer reads it (a copy): in every pass, so that
        the static and the dynamic pass compare alike."""
        if not self.observer or scenario.accelerometer.enabled:
            return scenario
        out = scenario.model_copy(deep=True)
        out.accelerometer.enabled = True
        return out


def service_delay_ms(opts: DynamicOptions, world: World, static_log: Track) -> float:
    """The delay the service is given: ``opts.delay_ms``, else the end-to-end delay measured on the static
    pass; HilError when it cannot be measured (`hil.report.end_to_end_delay` returned None)."""
    if opts.delay_ms is not None:
        return float(opts.delay_ms)
    delay = end_to_end_delay(world, static_log)
    if delay is None:
        raise HilError("the end-to-end delay could not be measured on the static pass: no lag of 0-60 ms "
                       "explains the correction as a linear function of the force (the truth holds an effect "
                       "far from linear in it, one with a history); give it with --delay-ms MS (measured on a "
                       "truth without it, or at commissioning)")
    return 1000.0 * delay


def commissioning_record(scenario: Scenario, truth: StiffnessModel) -> Record:
    """The process force at the tool and the stub's TCP deflection from its path (uncompensated), every ms."""
    world = World(scenario, truth.robot)
    stub = RobotStub(truth, scenario.robot, scenario.payload)
    ev = evaluate_uncompensated(world, stub, RECORD_PERIOD_S)
    q = np.array([world.path.q_ref_deg(x) for x in ev.t])
    nominal = truth.robot.frames(np.radians(q))[:, 7, :3, 3]
    return Record(ev.t - ev.t[0], world.force(ev.t), ev.p - nominal, "the HIL's uncompensated pass")


def tap_record(scenario: Scenario, truth: StiffnessModel, seed: int = 17, axes: tuple[int, ...] = (0, 1, 2),
               peak_n: float = TAP_N, q_deg=None) -> Record:
    """A tap test at the circle's centre (or at the joints ``q_deg``): a half-sine pulse of ``peak_n`` over `TAP_MS` along x, y and z (base
    axes; those in ``axes``) in turn, and the stub's TCP deflection, every ms, with `TAP_NOISE_M` of noise
    (1 sigma)."""
    stub = RobotStub(truth, scenario.robot, scenario.payload)
    t = np.arange(0.0, 3 * TAP_EVERY_S + 0.5, RECORD_PERIOD_S)

    def force(tt):
        tt = np.atleast_1d(tt)
        out = np.zeros((len(tt), 3))
        for k in axes:
            x = (tt - 0.3 - k * TAP_EVERY_S) / (TAP_MS / 1000.0)
            out[:, k] = np.where((x >= 0) & (x <= 1), peak_n * np.sin(np.pi * np.clip(x, 0, 1)), 0.0)
        return out

    q = np.tile(scenario.circle.center_q_deg if q_deg is None else q_deg, (len(t), 1))
    p = stub.actual(t, q, force, t[0], t[-1])[0]
    d = p - truth.robot.frames(np.radians(q[:1]))[0, 7, :3, 3]
    d += np.random.default_rng(seed).normal(0.0, TAP_NOISE_M, d.shape)
    return Record(t, force(t), d, "a tap test in the HIL")


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


def plan_register_map(rmap: RegisterMap, folder: Path) -> Path:
    """The register map ``rmap`` (the scenario's service config's) with the plan's two values added after its
    last from-PLC register, written into ``folder`` (docs/register_map.md, "The plan")."""
    data = rmap.extended(PLAN_VALUES)
    path = folder / "registers_plan.yaml"
    path.write_text(dump_yaml(data, sort_keys=False))
    return path


def service_dynamics(found: Identified | GivenModes, delay_ms: float, opts: DynamicOptions, scenario: Scenario,
                     world: World, folder: Path) -> dict:
    """The service config's overrides: ``dynamics`` with the identified modes (scaled by 1 + mode_error), the
    measured delay and, with the feedforward, the plan and a register map that carries it."""
    section = {"enabled": True, "delay_ms": round(delay_ms, 2), "structure": structure_section(found, opts)}
    if opts.predictor:
        section["predictor"] = {} if opts.predictor_hz is None else {"bandwidth_hz": opts.predictor_hz}
    out = {"dynamics": section}
    if opts.observer:
        h = opts.observer_horizon_ms if opts.observer_horizon_ms is not None else observer_horizon_ms(scenario)
        section["observer"] = {"modes": section["structure"]["modes"], "horizon_ms": round(h, 2)}
        if opts.observer_band_hz is not None:
            section["observer"]["band_hz"] = list(opts.observer_band_hz)
        if opts.follow:
            section["observer"]["follow"] = True
    if opts.feedforward:
        folder.mkdir(parents=True, exist_ok=True)
        write_plan(world, folder / "plan.csv")
        section["feedforward"] = {"source": "file", "file": str(folder / "plan.csv"),
                                  # the PLC program takes a read's answer a cycle after it sent it, then holds it
                                  "output_delay_ms": 1.5 * scenario.plc.period_ms + scenario.plc.extra_delay_ms}
        rmap = load_config(scenario.resolve(scenario.service)).register_map()
        out["plc"] = {"register_map": str(plan_register_map(rmap, folder))}
    return out


def observer_horizon_ms(scenario: Scenario) -> float:
    """From the box's value to the correction in the arm: the PLC passes the value it read at its cycle's
    start, its write lands a cycle later and the service reads it at its next cycle (2.5 PLC cycles); the
    correction is the PLC's command 1.5 PLC cycles after the service's output, and the drives reach a command a
    cycle later (5 in all), plus the extra delay; at most the observer's `MAX_HORIZON_MS`."""
    from stiffness.dynamics.observer import MAX_HORIZON_MS

    return min(5.0 * scenario.plc.period_ms + scenario.plc.extra_delay_ms, MAX_HORIZON_MS)


def structure_section(found: Identified | GivenModes, opts: DynamicOptions) -> dict:
    """``dynamics.structure`` of the identified modes, their frequencies scaled by 1 + ``opts.mode_error``."""
    structure = found.to_config()
    for m in structure["modes"]:
        m["hz"] = round(m["hz"] * (1.0 + opts.mode_error), 3)
    structure["added_damping"] = opts.added_damping
    return structure


@dataclass
class GivenModes:
    """The structure a file gives (``dynamics.structure``, as `stiffcomp modes -o` writes it), where the pass
    takes it instead of the tap test's identification."""

    structure: dict

    @classmethod
    def read(cls, path: Path) -> GivenModes:
        """HilError naming the file when it holds no ``dynamics.structure`` the service takes
        (`stiffness.dynamics.structure.read_structure`)."""
        from stiffness.dynamics.structure import read_structure
        from stiffness.errors import StiffnessError

        try:
            return cls(read_structure(path, "--modes").cfg.model_dump())
        except StiffnessError as e:
            raise HilError(str(e)) from e

    def to_config(self) -> dict:
        return {"modes": [dict(m) for m in self.structure["modes"]], "lag_ms": self.structure.get("lag_ms", 0.0)}


def identify_from_pass(scenario: Scenario, truth: StiffnessModel, opts: DynamicOptions) -> Identified | GivenModes:
    """Steps 1 and 2: the record (written to ``opts.record`` when given) and the modes found in it, or the modes
    ``opts.modes_file`` gives; HilError when the modes, their frequencies scaled by 1 + ``opts.mode_error``, are
    not a structure the service takes (found before any pass starts, not when the service refuses its
    config)."""
    from pydantic import ValidationError

    from stiffness.dynamics.structure import Structure
    from stiffness.files.yaml_schema import format_validation_error

    if opts.modes_file is not None:
        found = GivenModes.read(Path(opts.modes_file))
    else:
        rec = tap_record(scenario, truth) if opts.commissioning == "tap" else commissioning_record(scenario, truth)
        if opts.record is not None:
            write_record(rec, Path(opts.record))
        found = identify(rec, opts.n_modes)
    try:
        Structure.Config.model_validate(structure_section(found, opts))
    except ValidationError as e:
        why = "; ".join(line.removeprefix("-: ") for line in format_validation_error("-", e, prefix="dynamics.structure")
                        .splitlines())
        raise HilError(f"--mode-error {opts.mode_error:g}: the identified modes' frequencies times 1 + it are not what "
                       f"the service takes: {why}") from e
    return found


def figures(world: World, ev: Evaluation) -> dict:
    """The figures of the Done-when: the entry and exit windows' peaks, the steady mean, the mean and max (mm)."""
    w = window_errors(world, ev)
    mean, worst = errors(ev)
    return {"entry_peak_mm": w["entry_peak_mm"], "exit_peak_mm": w["exit_peak_mm"],
            "steady_mean_mm": w["steady_mean_mm"], "mean_error_mm": mean, "max_error_mm": worst}


def compare(scenario: Scenario, truth: StiffnessModel, model_path: Path,
            cases: list[tuple[float, list[DynamicOptions]]], folder: Path | None = None, run=None,
            progress=None) -> dict:
    """Static against dynamic compensation on one scenario: the modes identified once (the first variant's
    commissioning), the uncompensated pass once; per case (an extra delay of the PLC and its variants) the
    static pass (its end-to-end delay measured) and one dynamic pass per variant. ``run``: the pass runner (default lock step,
    `hil.lockstep.run_lockstep`; `hil.run.run_pass` for real time); ``progress(text)`` is told each result.

    Returns {"identified", "uncompensated", "cases": [{"extra_delay_ms", "delay_ms", "static",
    "dynamic": [{"options", "figures", "entry_ratio", "exit_ratio"}]}]}."""
    import copy
    import tempfile

    from .lockstep import run_lockstep

    run = run or run_lockstep
    say = progress or (lambda text: None)
    found = identify_from_pass(scenario, truth, cases[0][1][0])
    say(f"identified: {found.to_config()}")
    out = {"identified": found.to_config(), "cases": []}
    with tempfile.TemporaryDirectory(prefix="stiffcomp-dynamics-") as tmp:
        base = Path(folder or tmp)

        def one(sc, name, compensate, overrides=None):
            r = run(sc, truth, model_path, compensate, base / name, overrides)
            return r, evaluate_pass(sc, truth, r)[1]

        world = World(scenario, truth.robot)
        out["uncompensated"] = figures(world, one(scenario, "uncompensated", False)[1])
        for extra, variants in cases:
            sc = scenario.model_copy(deep=True)
            sc.path = scenario.path
            sc.plc.extra_delay_ms = extra
            sc.accelerometer.enabled |= any(v.observer for v in variants)     # the static pass measures it too
            static_pass, static = one(sc, f"static_{extra:g}", True)
            delay_ms = service_delay_ms(DynamicOptions(), world, static_pass.log)   # measured
            case = {"extra_delay_ms": extra, "delay_ms": delay_ms, "static": figures(world, static), "dynamic": []}
            say(f"extra delay {extra:g} ms: end-to-end delay {delay_ms:.2f} ms, static {case['static']}")
            for k, opts in enumerate(variants):
                over = service_dynamics(found, delay_ms, opts, sc, world, base / f"plan_{extra:g}_{k}")
                f = figures(world, one(sc, f"dynamic_{extra:g}_{k}", True, copy.deepcopy(over))[1])
                row = {"options": opts, "figures": f,
                       "entry_ratio": f["entry_peak_mm"] / case["static"]["entry_peak_mm"],
                       "exit_ratio": f["exit_peak_mm"] / case["static"]["exit_peak_mm"]}
                case["dynamic"].append(row)
                say(f"  {opts}: {f}")
            out["cases"].append(case)
    return out
