"""`stiffcomp hil circle`: the closed loop with virtual devices, the paper's circle (docs/hil.md).

Runs the service, a virtual ATI sensor and a virtual PLC in separate processes in real time, twice on
the same force trace (without, then with compensation), and prints the path errors.
"""

from __future__ import annotations

import json
from pathlib import Path

from hil.scenario import DEFAULT_SCENARIO, load_scenario
from robot_road import registry
from stiffness.errors import OutputError

from .common import check_count, check_number, check_output_file


def register(sub) -> None:
    p = sub.add_parser("hil", help="hardware-in-the-loop runs with virtual devices")
    hs = p.add_subparsers(dest="hil_command", metavar="RUN", required=True)
    c = hs.add_parser("circle", help="mill the paper's circle without and with compensation (Fig. 8)")
    c.add_argument("--scenario", default=str(DEFAULT_SCENARIO), help="scenario YAML (default: config/hil/circle.yaml)")
    c.add_argument("--truth", default=None, metavar="T.yaml", help="the robot stub's truth model")
    c.add_argument("--model", default=None, metavar="M.yaml", help="the model the service compensates with")
    c.add_argument("--no-compensation", action="store_true", help="only the pass without compensation")
    c.add_argument("--report", default=None, metavar="DIR", help="write hil_circle.png, summary.json, errors")
    c.add_argument("--json", action="store_true", help="print the summary as JSON")
    c.add_argument("--trace", default=None, metavar="FILE",
                   help="the service records every cycle of the (compensated) cut to FILE (.csv or .parquet)")
    c.add_argument("--cmm", default=None, metavar="FILE.csv|FILE.qif",
                   help="write the cut part as the virtual CMM measures it: a part CSV, or QIF 3 results to a .qif "
                        "file (docs/part_format.md)")
    c.add_argument("--probe", default=None, metavar="FILE.csv",
                   help="after the cut the robot probes the part it cut (the scenario's probe section) and writes the "
                        "probe log to FILE (docs/part_format.md)")
    c.add_argument("--repeat", default="1", metavar="N",
                   help="cut each pass N times (ISO 9283's cycles) for path_accuracy_mm and path_repeatability_mm "
                        "(default 1: no repeatability)")
    c.add_argument("--extra-delay-ms", type=float, default=None, metavar="MS",
                   help="the virtual PLC applies each correction this much later (the scenario's plc.extra_delay_ms)")
    c.add_argument("--robot-interface", choices=registry.names(), default=None,
                   help="cut through the robot road instead of the PLC: a virtual KUKA RSI or ABB EGM robot on its "
                        "own clock, set up as the shipped config/robot_<interface>.yaml (RSI at 4 ms; EGM path "
                        "correction every 48 ms), the service without a PLC (docs/robot.md)")
    c.add_argument("--robot-config", default=None, metavar="CONFIG.yaml",
                   help="with --robot-interface: take robot.<interface> from this service config instead of the "
                        "shipped one (e.g. EGM path corrections every 24 ms)")
    c.add_argument("--plc-program", default=None, metavar="DIR",
                   help="the TwinCAT program the virtual PLC runs (a folder of .TcPOU/.TcDUT/.TcGVL, or one with "
                        "twincat/ in it); default: the library `stiffcomp plc-library --main-block modbus` writes for "
                        "each pass's config")
    c.add_argument("--accelerometer", action="store_true",
                   help="a virtual EP3751 at the tool, read by the PLC and the service (the scenario's "
                        "accelerometer section; docs/accelerometer.md): the trace carries the arm's acceleration")
    c.add_argument("--lockstep", action="store_true",
                   help="step the service, sensor and PLC together in one process, as fast as the host runs "
                        "them (deterministic; no real time, no protocols' transport)")
    c.add_argument("--center-q", type=float, nargs=6, default=None, metavar=("Q1", "Q2", "Q3", "Q4", "Q5", "Q6"),
                   help="cut the circle here instead (joints at its centre, deg; the scenario's circle.center_q_deg)")
    d = c.add_argument_group("dynamic compensation (docs/dynamics.md)")
    d.add_argument("--dynamic-compensation", action="store_true",
                   help="a third pass with the service's dynamic path on: the modes identified from a tap test the "
                        "robot stub answers (as `stiffcomp modes` would), the delay measured on the static pass")
    d.add_argument("--mode-error", type=float, default=0.0, metavar="F",
                   help="the service's mode frequencies scaled by 1 + F (a model that is off; e.g. 0.2, -0.2)")
    d.add_argument("--added-damping", type=float, default=0.0, metavar="Z",
                   help="dynamics.structure.added_damping: the robust modal filter (0: the modes as identified)")
    d.add_argument("--feedforward", action="store_true",
                   help="also the feedforward from the process plan (the PLC writes its program time)")
    d.add_argument("--no-predictor", action="store_true", help="the dynamic pass without the wrench predictor")
    d.add_argument("--delay-ms", type=float, default=None, metavar="MS",
                   help="the service's dynamics.delay_ms (default: the end-to-end delay measured on the static pass)")
    d.add_argument("--modes", default=None, metavar="FILE.yaml",
                   help="the dynamic pass with the modes (and lag) of this file's dynamics.structure, as `stiffcomp "
                        "modes -o` writes it (from a tap test or a cut's trace), instead of the stub's tap test")
    d.add_argument("--observer", action="store_true",
                   help="also the accelerometer's observer (dynamics.observer; the virtual box on in every pass)")
    d.add_argument("--modes-data", default=None, metavar="FILE.csv",
                   help="write the commissioning record (the tap test's force and the stub's deflection) for `stiffcomp modes`")
    c.set_defaults(func=run)


def _validated(section, name: str, key: str, value, option: str):
    """``section`` (a scenario's pydantic section) with ``key`` = ``value``, validated as the scenario file's
    value is; ConfigError names the option, the key and the bound."""
    from pydantic import ValidationError

    from stiffness.errors import ConfigError
    from stiffness.files.yaml_schema import format_validation_error

    try:
        return type(section).model_validate({**section.model_dump(), key: value})
    except ValidationError as e:
        raise ConfigError(format_validation_error(option, e, prefix=name)) from e


# the options of the dynamic pass, and whether each was given
_DYNAMIC = {"--mode-error": lambda a: a.mode_error != 0.0, "--added-damping": lambda a: a.added_damping != 0.0,
            "--feedforward": lambda a: a.feedforward, "--no-predictor": lambda a: a.no_predictor,
            "--delay-ms": lambda a: a.delay_ms is not None, "--modes-data": lambda a: a.modes_data is not None,
            "--modes": lambda a: a.modes is not None, "--observer": lambda a: a.observer}


def _service_value(option: str, schema, key: str, value, prefix: str):
    """``value`` checked as the service config's ``prefix.key`` (``schema``'s field) is; ConfigError naming
    the option, the key and the bound."""
    from typing import Annotated

    from pydantic import TypeAdapter, ValidationError

    from stiffness.errors import ConfigError
    from stiffness.files.yaml_schema import format_validation_error

    field = schema.model_fields[key]
    try:
        return TypeAdapter(Annotated[field.annotation, field]).validate_python(value)
    except ValidationError as e:
        raise ConfigError(format_validation_error(option, e, prefix=f"{prefix}.{key}")) from e


def _check_dynamic_options(args) -> None:
    """An option of the dynamic pass without it, or the dynamic pass without the static one it builds on, is
    refused (it would be ignored); --delay-ms and --added-damping are checked as the service's config checks
    dynamics.delay_ms and dynamics.structure.added_damping, --mode-error keeps the frequencies above 0."""
    from service.dynamics import DynamicsConfig
    from stiffness.dynamics.structure import Structure
    from stiffness.errors import ConfigError

    given = [o for o, is_given in _DYNAMIC.items() if is_given(args)]
    if given and not args.dynamic_compensation:
        raise ConfigError(f"{', '.join(given)}: only with --dynamic-compensation")
    if args.dynamic_compensation and args.no_compensation:
        raise ConfigError("--dynamic-compensation builds on the compensated pass (its delay): drop --no-compensation")
    if args.modes is not None and args.modes_data is not None:
        raise ConfigError("--modes-data writes the stub's tap test, which --modes replaces: give one of them")
    if args.delay_ms is not None:
        _service_value("--delay-ms", DynamicsConfig, "delay_ms", args.delay_ms, "dynamics")
    _service_value("--added-damping", Structure.Config, "added_damping", args.added_damping, "dynamics.structure")
    check_number("--mode-error", args.mode_error, "the service's mode frequencies are the identified ones times "
                 "1 + F, which must stay above 0", above=-1.0)


def _check_outputs_and_reach(args, scenario) -> None:
    """The files the run writes at its end go into folders that exist, and the circle can be followed from
    its centre's pose (the inverse kinematics of its points): each checked before any pass starts."""
    from hil.path import CirclePath, IkError
    from stiffness.errors import ConfigError
    from stiffness.model.stiffness_model import StiffnessModel

    for option, path in (("--cmm", args.cmm), ("--probe", args.probe), ("--modes-data", args.modes_data)):
        if path is not None:
            check_output_file(option, path)
    for option, path, formats in (("--cmm", args.cmm, (".csv", ".qif")), ("--probe", args.probe, (".csv",))):
        if path is not None and Path(path).suffix.lower() not in formats:
            raise OutputError(f"{option} {path}: the suffix must be {' or '.join(formats)} (the file's format: "
                              "docs/part_format.md)")
    robot = StiffnessModel.from_yaml(args.truth or scenario.resolve(scenario.truth)).robot
    try:
        CirclePath(robot, scenario.circle)
    except IkError as e:
        where = (f"--center-q {' '.join(f'{q:g}' for q in args.center_q)}" if args.center_q is not None else
                 f"{args.scenario}: circle.center_q_deg")
        own = " ".join(f"{q:g}" for q in load_scenario(args.scenario).circle.center_q_deg)
        raise ConfigError(f"{where}: the circle of {scenario.circle.radius_mm:g} mm about the tool at this pose cannot "
                          f"be followed: {e} (a point out of the arm's reach, or a singular pose such as a stretched "
                          f"arm); put its centre where the arm reaches all round (the scenario's: {own})") from e


def _iso_line(s: dict, compensated: bool) -> str:
    """The ISO 9283 path figures of the summary ``s`` in one line."""
    def both(key: str) -> str:
        if s[key] is None:
            return "-"
        where = key.replace("_mm", "_at_deg")

        def one(suffix: str) -> str:
            return f"{s[key + suffix]:.3f} mm at {s[where + suffix]:.1f} deg"

        return f"{one('_uncompensated')} / {one('')}" if compensated else one("")

    return (f"ISO 9283 over {s['repeats']} cut(s) of each pass{', without / with compensation' if compensated else ''}"
            f": path accuracy AT_p {both('path_accuracy_mm')}, path repeatability RT_p {both('path_repeatability_mm')}")


def _robot_section(args) -> dict | None:
    """robot.<interface> of ``--robot-config``, or None (the shipped one); ConfigError names the file and key."""
    if args.robot_config is None:
        return None
    from stiffness.errors import ConfigError
    from stiffness.files.yaml_syntax import read_yaml

    if args.robot_interface is None:
        raise ConfigError("--robot-config sets up the robot road: give --robot-interface too")
    section = (read_yaml(args.robot_config).get("robot") or {}).get(args.robot_interface)
    if not isinstance(section, dict):
        raise ConfigError(f"{args.robot_config}: robot.{args.robot_interface} is missing (--robot-config with "
                          f"--robot-interface {args.robot_interface})")
    from hil.circle import check_robot_section

    return check_robot_section(args.robot_interface, section)


def run(args) -> int:
    from hil.circle import run_circle

    scenario = load_scenario(args.scenario)
    if args.center_q is not None:
        scenario.circle = _validated(scenario.circle, "circle", "center_q_deg", list(args.center_q), "--center-q")
    if args.extra_delay_ms is not None:
        scenario.plc = _validated(scenario.plc, "plc", "extra_delay_ms", args.extra_delay_ms, "--extra-delay-ms")
    if args.accelerometer:
        scenario.accelerometer.enabled = True
    _check_dynamic_options(args)
    repeat = check_count("--repeat", args.repeat)
    if args.trace is not None:
        from service.trace import TraceOptions

        TraceOptions(Path(args.trace)).check()          # a bad name fails now, not after the first pass
    _check_outputs_and_reach(args, scenario)
    robot_section = _robot_section(args)
    dynamic = None
    if args.dynamic_compensation:
        from hil.dynamics import DynamicOptions

        dynamic = DynamicOptions(args.mode_error, args.added_damping, args.feedforward,
                                 record=Path(args.modes_data) if args.modes_data else None,
                                 predictor=not args.no_predictor, delay_ms=args.delay_ms, observer=args.observer,
                                 modes_file=Path(args.modes) if args.modes else None)
    res = run_circle(scenario, Path(args.truth) if args.truth else None, Path(args.model) if args.model else None,
                     compensation=not args.no_compensation, report=Path(args.report) if args.report else None,
                     trace=Path(args.trace) if args.trace else None, cmm=Path(args.cmm) if args.cmm else None,
                     lockstep=args.lockstep, dynamic=dynamic, repeat=repeat, robot_interface=args.robot_interface,
                     robot_section=robot_section, probe_log=Path(args.probe) if args.probe else None,
                     plc_program=Path(args.plc_program) if args.plc_program else None)
    s = res.summary
    if args.json:
        print(json.dumps(s, indent=2))
    else:
        print(f"path error without compensation: mean {s['mean_error_mm_uncompensated']:.3f} mm, "
              f"max {s['max_error_mm_uncompensated']:.3f} mm")
        if "mean_error_mm_static" in s:
            print(f"path error, static compensation:  mean {s['mean_error_mm_static']:.3f} mm, "
                  f"max {s['max_error_mm_static']:.3f} mm; entry/exit peaks {s['entry_peak_mm_static']:.3f} / "
                  f"{s['exit_peak_mm_static']:.3f} mm")
        if not args.no_compensation:
            red = 100 * (1 - s["mean_error_mm"] / s["mean_error_mm_uncompensated"])
            what = "dynamic compensation:" if "mean_error_mm_static" in s else "with compensation:   "
            print(f"path error, {what} mean {s['mean_error_mm']:.3f} mm, "
                  f"max {s['max_error_mm']:.3f} mm ({red:.0f} % less); entry/exit peaks {s['entry_peak_mm']:.3f} / "
                  f"{s['exit_peak_mm']:.3f} mm; end-to-end delay {s['delay_ms']} ms")
        print(f"part error (virtual CMM, mean |normal deviation|): {s['part_error_mm']:.3f} mm")
        print(_iso_line(s, not args.no_compensation))
        print(f"service: {s['cycles']} cycles, {s['exceed_count']} exceeded: {s['timing']['verdict']}")
        if args.robot_interface:
            print(f"robot road {args.robot_interface}: {s['late_answers']} late answers, answer round trip p99 "
                  f"{s['reply_latency_p99_ms']} ms at the robot")
        if s.get("plc_program"):
            prog = s["plc_program"]
            print(f"PLC program: {prog['folder']} (" + ", ".join(f"{name} sha256 {digest[:12]}" for name, digest
                                                         in prog["files"].items()) + ")")
        if args.trace:
            print(f"trace: {args.trace}")
        if args.cmm:
            qif = args.cmm.lower().endswith(".qif")
            print(f"part measurement: {args.cmm}" + (f" (QIF 3; `stiffcomp part` reads it with "
                                                       f"{res.cmm[list(res.passes)[-1]].qif_options})" if qif else ""))
        if args.probe:
            print(f"probe log: {args.probe} (the robot's own touches; `stiffcomp part` reads it without a part frame)")
        if args.report:
            print(f"report: {Path(args.report) / 'hil_circle.png'}, {Path(args.report) / 'summary.json'}")
    return 0
