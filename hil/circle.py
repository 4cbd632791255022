"""`stiffcomp hil circle`: mill the circle twice on the same force trace, without then with compensation."""

from __future__ import annotations

import copy
import json
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from stiffness.files.yaml_schema import deep_update
from stiffness.model.stiffness_model import StiffnessModel

from .cmm import CmmResult, measure
from .delay_band import delay_band_ms, device_lateness, timing_with_delays
from .device_log import DeviceLog, RobotLog
from .dynamics import (
    DynamicOptions,
    identify_from_pass,
    service_delay_ms,
    service_dynamics,
    structure_section,
)
from .iso9283 import circle_figures
from .lockstep import run_lockstep
from .probe import ProbeResult, probe
from .report import Evaluation, end_to_end_delay, errors, evaluate_pass, plot, window_errors, windows_figure
from .run import Faults, HilError, PassResult, run_pass
from .scenario import Scenario
from .world import World


@dataclass
class CircleResult:
    """Both passes, their evaluations and the summary printed by the command."""

    summary: dict
    passes: dict[str, PassResult]
    evaluations: dict[str, Evaluation]
    world: World
    cmm: dict[str, CmmResult]


# the share of deadlines exceeded per cycle run (task exceed_count / cycles) that makes a pass's figures doubtful
BUSY_SHARE, OVERLOADED_SHARE = 0.01, 0.2


def timing_verdict(cycles: int, exceeded: int) -> dict:
    """Whether a pass's cycle timing lets its path errors stand for the service, in words.

    ``exceeded`` is the task's exceed counter (overrunning cycles plus the deadlines skipped after them),
    so the share may pass 100 % when the host could not even run every cycle."""
    share = exceeded / cycles if cycles else 1.0
    pct = f"{100 * share:.0f} %" if share >= 0.01 else f"{100 * share:.2f} %"
    if share <= BUSY_SHARE:
        return {"exceeded_share": round(share, 4), "trustworthy": True,
                "verdict": f"the 1 ms cycle kept its deadlines ({pct} exceeded): the figures show the service"}
    if share <= OVERLOADED_SHARE:
        return {"exceeded_share": round(share, 4), "trustworthy": True,
                "verdict": f"the host was busy ({pct} of deadlines exceeded): the correction was late in places, "
                           "so the compensated error is a little worse than on a quiet host"}
    return {"exceeded_share": round(share, 4), "trustworthy": False,
            "verdict": f"the host was too loaded for a 1 ms cycle ({pct} of deadlines exceeded): the correction "
                       "was stale for much of the pass, so the compensated error is an upper bound, not what the "
                       "service does; run again on a quiet machine (or with cycle.realtime_priority and a "
                       "cycle.cpu of its own) before trusting these figures"}


def run_circle(scenario: Scenario, truth_path: Path | None = None, model_path: Path | None = None,
               compensation: bool = True, report: Path | None = None, workdir: Path | None = None,
               faults: Faults | None = None, service_overrides: dict | None = None,
               trace: Path | None = None, cmm: Path | None = None, lockstep: bool = False,
               dynamic: DynamicOptions | None = None, robot_interface: str | None = None,
               repeat: int = 1, robot_section: dict | None = None, probe_log: Path | None = None,
               plc_program: Path | None = None) -> CircleResult:
    """Run the passes (uncompensated, then compensated unless ``compensation`` is False) and summarise.

    ``faults`` are injected in the compensated pass only. The last pass (the compensated one, or the only one)
    writes the service's ``trace`` (`stiffcomp run --trace`) and the virtual CMM's points of the part it cut to
    ``cmm`` (`hil.cmm`); the summary's ``part_error_mm`` is that part's mean error. ``lockstep``: each pass in one
    process as fast as the host runs it (`hil.lockstep`), not in real time. ``dynamic``: a third pass with the
    dynamic compensation (`hil.dynamics`): the modes identified from a tap test the stub answers (or a file's),
    the delay measured on the static one (or ``dynamic.delay_ms``), with its observer the accelerometer on in
    every pass; the summary's figures are then the dynamic pass's, with the static pass's as ``*_static`` twins.
    ``robot_interface`` (``kuka_rsi``, ``abb_egm``): each pass through the robot road, a virtual robot of that
    interface in the PLC's place (`hil.robot_process`), set up as ``robot_section`` says (default: the shipped
    config/robot_<interface>.yaml's; EGM in path mode at 48 ms, its joint mode refused: position guidance runs
    no RAPID path, ABB's EGM manual). ``repeat``: each pass cut that many times (ISO 9283's n cycles) for its
    path accuracy and repeatability (`hil.iso9283`); the first cut of each is the one every other figure, the
    trace and the part come from. ``probe_log``: after the last pass the robot probes the part it cut
    (`hil.probe`) and the log is written there. ``plc_program``: the virtual PLC's TwinCAT program
    (`hil.run.pass_program`); the summary names its files and their sha256.
    """
    scenario = dynamic.measured_by(scenario) if dynamic is not None else scenario
    truth = StiffnessModel.from_yaml(truth_path or scenario.resolve(scenario.truth))
    model_path = Path(model_path or scenario.resolve(scenario.model))
    StiffnessModel.from_yaml(model_path)               # a bad model fails here, before any process starts
    _real_time_only(lockstep, faults, robot_interface)
    robot_section = check_robot_section(robot_interface, robot_section)
    found = identify_from_pass(scenario, truth, dynamic) if dynamic is not None and compensation else None
    names = ["uncompensated", *(["compensated"] if compensation else []), *(["dynamic"] if found else [])]
    passes: dict[str, PassResult] = {}
    again: dict[str, list[Evaluation]] = {}            # the evaluations of each pass's further repeats
    delays: list[float | None] = []                    # the end-to-end delay (s) of the compensated pass's repeats
    with tempfile.TemporaryDirectory(prefix="stiffcomp-hil-") as tmp:
        base = Path(workdir or tmp)
        overrides = dict(service_overrides or {})

        def cut_once(name: str, folder: Path, traced: Path | None) -> PassResult:
            if lockstep:
                return run_lockstep(scenario, truth, model_path, name != "uncompensated", folder, overrides, traced,
                                    plc_program)
            return run_pass(scenario, truth, model_path, name != "uncompensated", folder,
                            faults if name == "compensated" else None, overrides, traced, robot_interface,
                            robot_section, plc_program)
        for name in names:
            last = name == names[-1]
            if name == "dynamic":
                world = World(scenario, truth.robot)
                delay_ms = service_delay_ms(dynamic, world, passes["compensated"].log)
                overrides = deep_update(copy.deepcopy(overrides), service_dynamics(
                    found, delay_ms, dynamic, scenario, world, base / "dynamic"))
            passes[name] = cut_once(name, base / name, trace if last else None)
            again[name] = []
            for k in range(2, repeat + 1):
                result = cut_once(name, base / f"{name}_{k}", None)
                world_k, ev = evaluate_pass(scenario, truth, result)
                again[name].append(ev)
                if name == "compensated":          # each repeat's timing is checked, not the first cut's alone
                    delays.append(end_to_end_delay(world_k, result.log))
    evals, parts, world = {}, {}, None
    for name, r in passes.items():
        world, evals[name] = evaluate_pass(scenario, truth, r)
        parts[name] = measure(scenario, world, evals[name])
    band = delay_band_ms(scenario, service_overrides, robot_interface)
    summary = summarise(world, passes, evals, parts, lockstep, again, band, delays)
    summary["robot_interface"] = robot_interface or "none"
    summary["plc_program"] = passes[names[-1]].extra.get("plc_program")      # None on the robot road
    if found is not None:
        summary["dynamics"] = dynamics_summary(found, dynamic)
    if cmm is not None:
        parts[names[-1]].write(cmm)
    if probe_log is not None:
        probe(scenario, world, truth.robot, evals[names[-1]]).write(probe_log)
    if report is not None:
        write_report(Path(report), world, evals, passes, summary)
    return CircleResult(summary, passes, evals, world, parts)


def _real_time_only(lockstep: bool, faults, robot_interface) -> None:
    """HilError for what runs in real time only, asked in lock step: injected faults, the robot road."""
    if lockstep and faults is not None:
        raise HilError("faults are injected in real time only: run without --lockstep")
    if lockstep and robot_interface is not None:
        raise HilError("the robot road runs on the robot's clock, in real time only: run without --lockstep")


def dynamics_summary(found, dynamic: DynamicOptions) -> dict:
    """The summary's ``dynamics``: the modes the dynamic pass identified (or the file gave) and how it was set
    up; what the tap test's modes explain (null for a file's)."""
    given = dynamic.modes_file is not None
    return {"structure": structure_section(found, dynamic), "mode_error": dynamic.mode_error,
            "observer": dynamic.observer, "modes_file": str(dynamic.modes_file) if given else None,
            "predictor": dynamic.predictor, "feedforward": dynamic.feedforward,
            "explained": None if given else round(found.explained, 5),
            "explained_static": None if given else round(found.explained_static, 5)}


def summarise(world: World, passes: dict[str, PassResult], evals: dict[str, Evaluation],
              parts: dict[str, CmmResult], lockstep: bool, again: dict[str, list[Evaluation]] | None = None,
              band: tuple[float, float] | None = None, repeat_delays: list[float | None] | None = None) -> dict:
    """The summary of the passes: the last one's figures (the compensated or the dynamic pass), the
    uncompensated pass's as ``_uncompensated`` twins and, with a dynamic pass, the static one's as ``_static``.
    ``again``: the evaluations of each pass's further repeats, for its ISO 9283 path figures. ``band``: the
    end-to-end delay the loop can show (`hil.delay_band`); a delay outside it, the first cut's or a repeat's
    (``repeat_delays``, s, the compensated pass's further cuts), makes the timing untrustworthy, naming the
    virtual device (the PLC, the robot: the type of the pass's log) when it did not keep up its cycles
    (`hil.delay_band.device_lateness`)."""
    last = list(passes)[-1]
    mean_u, max_u = errors(evals["uncompensated"])
    mean_c, max_c = errors(evals[last])
    stats = passes[last].stats[-1]
    summary = {"mean_error_mm": round(mean_c, 4), "max_error_mm": round(max_c, 4),
               "mean_error_mm_uncompensated": round(mean_u, 4), "max_error_mm_uncompensated": round(max_u, 4),
               "cycles": int(stats.get("cycles", 0)), "exceed_count": int(stats.get("exceed_count", 0))}
    twins = [(last, ""), ("uncompensated", "_uncompensated")]
    if last == "dynamic":
        twins.append(("compensated", "_static"))
        mean_s, max_s = errors(evals["compensated"])
        summary.update(mean_error_mm_static=round(mean_s, 4), max_error_mm_static=round(max_s, 4))
    for name, suffix in twins:
        summary.update({k + suffix: round(v, 4) for k, v in window_errors(world, evals[name]).items()})
        iso = circle_figures(world.path, [evals[name], *(again or {}).get(name, [])], len(world.path.phi) - 1)
        summary["path_accuracy_mm" + suffix] = round(iso.accuracy, 4)
        summary["path_repeatability_mm" + suffix] = None if iso.repeatability is None else round(iso.repeatability, 4)
        summary["path_accuracy_at_deg" + suffix] = round(iso.worst_accuracy_at, 2)
        summary["path_repeatability_at_deg" + suffix] = (None if iso.worst_repeatability_at is None else
                                                         round(iso.worst_repeatability_at, 2))
    summary["repeats"] = 1 + len((again or {}).get(last, []))
    delay = end_to_end_delay(world, passes["compensated"].log) if "compensated" in passes else None
    summary["delay_ms"] = None if delay is None else round(1000.0 * delay, 2)
    summary.update(robot_road(passes[last].log))
    summary["part_error_mm"] = round(parts[last].part_error_mm, 4)
    summary["part_error_mm_uncompensated"] = round(parts["uncompensated"].part_error_mm, 4)
    summary["timing"] = (timing_verdict(summary["cycles"], summary["exceed_count"]) if not lockstep else
                         {"exceeded_share": 0.0, "trustworthy": True,
                          "verdict": "in lock step (no real time): the figures show the service's arithmetic, not its timing"})
    summary["delay_ms_repeats"] = [None if d is None else round(1000.0 * d, 2) for d in repeat_delays or []]
    if band is not None:
        summary["delay_band_ms"] = [round(band[0], 2), round(band[1], 2)]
        log = passes["compensated"].log if "compensated" in passes else None
        cause = (device_lateness(log.t, world.t_end, 1000.0 * log.period, log.device)
                 if log is not None and not lockstep else None)
        summary["timing"] = timing_with_delays(summary["timing"], [summary["delay_ms"], *summary["delay_ms_repeats"]],
                                               band, cause)
    return summary


def check_robot_section(interface: str | None, section: dict | None) -> dict | None:
    """The robot road's sub-section for a cut: ``section``, or the shipped robot config's; HilError for one the
    circle cannot be cut with (EGM's joint mode, position guidance, follows no RAPID path: it holds a pose)."""
    if interface is None:
        return None
    from pydantic import ValidationError

    from robot_road.settings import RobotSettings
    from stiffness.files.yaml_schema import format_validation_error

    from .run import shipped_robot_section

    section = dict(section if section is not None else shipped_robot_section(interface))
    try:
        s = RobotSettings.model_validate({"interface": interface, interface: section})
    except ValidationError as e:
        raise HilError(format_validation_error("the robot road's section", e, prefix="robot")) from e
    why = s.section.follows_no_path()
    if why:
        raise HilError(f"{why}: it holds a pose, it cannot cut the circle; cut with the shipped config's robot "
                       "side, which follows its path")
    return section


def robot_road(log: DeviceLog) -> dict:
    """The robot road's figures of a pass, from its virtual robot's log: the interface's answers that came late
    (or not at all) and the 99th percentile of the answers' round trip at the robot, in ms (None with a PLC)."""
    if not isinstance(log, RobotLog):
        return {"late_answers": None, "reply_latency_p99_ms": None}
    return {"late_answers": log.late, "reply_latency_p99_ms": log.reply_latency_p99_ms()}


@dataclass
class Cut:
    """One compensated cut: its path error (mm), the part the virtual CMM measured, the pass itself, and the
    robot's own probe of the part when asked for."""

    mean_error_mm: float
    max_error_mm: float
    part: CmmResult
    result: PassResult
    probed: ProbeResult | None = None


def cut(scenario: Scenario, truth_path: Path, model_path: Path, workdir: Path, trace: Path | None = None,
        cmm: Path | None = None, lockstep: bool = True, robot_interface: str | None = None,
        robot_section: dict | None = None, probe_log: Path | None = None) -> Cut:
    """Cut the circle once with compensation (the learning loop: cut, measure, learn, cut again); writes
    the service's ``trace``, the virtual CMM's ``cmm`` and the robot's own ``probe_log`` (`hil.probe`) when
    given. ``robot_interface``: through the robot road (in real time), as `run_circle` says."""
    truth = StiffnessModel.from_yaml(truth_path)
    if robot_interface is not None:
        if lockstep:
            raise HilError("the robot road runs on the robot's clock, in real time only: run without --lockstep")
        result = run_pass(scenario, truth, Path(model_path), True, Path(workdir), trace=trace,
                          robot_interface=robot_interface,
                          robot_section=check_robot_section(robot_interface, robot_section))
    else:
        run = run_lockstep if lockstep else run_pass
        result = run(scenario, truth, Path(model_path), True, Path(workdir), trace=trace)
    world, ev = evaluate_pass(scenario, truth, result)
    part = measure(scenario, world, ev)
    if cmm is not None:
        part.write(cmm)
    probed = probe(scenario, world, truth.robot, ev) if probe_log is not None else None
    if probed is not None:
        probed.write(probe_log)
    mean, worst = errors(ev)
    return Cut(mean, worst, part, result, probed)


def write_report(folder: Path, world: World, evals: dict[str, Evaluation], passes: dict[str, PassResult],
                 summary: dict) -> None:
    """hil_circle.png (Fig. 8), summary.json (with the task statistics) and the per-cycle errors."""
    folder.mkdir(parents=True, exist_ok=True)
    plot(world, evals, folder / "hil_circle.png")
    windows_figure(world, evals).savefig(folder / "hil_windows.png", dpi=110)
    detail = dict(summary)
    detail["reduction_pct"] = (round(100.0 * (1 - summary["mean_error_mm"] / summary["mean_error_mm_uncompensated"]),
                                     1) if summary["mean_error_mm_uncompensated"] > 0 else None)
    detail["service_stats"] = {k: p.stats for k, p in passes.items()}
    detail[next(iter(passes.values())).log.kind] = {k: p.log.counts() for k, p in passes.items()}
    (folder / "summary.json").write_text(json.dumps(detail, indent=2) + "\n")
    for k, ev in evals.items():
        c = ev.cut
        np.savetxt(folder / f"errors_{k}.csv", np.column_stack([ev.t[c], np.degrees(ev.angle[c]), ev.err_mm[c]]),
                   delimiter=",", header="t_s,angle_deg,radial_error_mm", comments="", fmt="%.6f")
