"""`stiffcomp robot-programs -o DIR`: write the robot controllers' programs (those shipped in
cell/robot/generated/: KUKA KRL, ABB RAPID and their configuration files) from their plans (docs/robot.md, docs/part.md).

Each program goes through its language's writer (cell/robot/krl.py, cell/robot/rapid.py), which refuses one that
breaks a rule of the maker's manual and names the rule and the line; the configs are read as `stiffcomp run --check`
reads them. What a config must change for the programs (the RSI cut's 12 ms cycle) is printed as a note."""

from __future__ import annotations

import sys
from pathlib import Path

from cell.robot.plan import CONFIGS, ROBOT, SCENARIO
from cell.robot.programs import generate

from .common import check_output_folder, write_output


def register(sub) -> None:
    p = sub.add_parser("robot-programs", help="write the KUKA and ABB programs of cell/robot/generated/ from their plans")
    p.add_argument("-o", "--output", required=True, help="folder to write kuka_rsi/, abb_egm/ and probe/ into")
    p.add_argument("--config", action="append", metavar="CONFIG",
                   help="a service config with a robot section, once per interface (default: "
                        + ", ".join(str(c.relative_to(c.parents[1])) for c in CONFIGS) + ")")
    p.add_argument("--scenario", default=str(SCENARIO), help="the HIL scenario whose probe section is the probe plan")
    p.add_argument("--robot", default=str(ROBOT), help="the robot YAML whose tcp is the probe's frame")
    p.set_defaults(func=run)


def run(args) -> int:
    out = check_output_folder("-o", args.output)
    configs = tuple(Path(c) for c in args.config) if args.config else CONFIGS
    programs = generate(configs, Path(args.scenario), Path(args.robot))
    for rel, text in programs.files.items():
        write_output(out / rel, lambda p, text=text: p.write_bytes(text.encode("ascii")))
    print(f"robot-programs: {len(programs.files)} files in {out}")
    for note in programs.notes:
        print(f"robot-programs: note: {note}", file=sys.stderr)
    return 0
