"""A CMM's QIF 3 results file as a part (docs/part_format.md, "QIF"): the options that supply what QIF does not
carry, the reader chosen by the file's name, and `stiffcomp part features FILE.qif [--json]`."""

from __future__ import annotations

import sys

from .common import check_number, print_json


def is_qif(name: str) -> bool:
    return str(name).lower().endswith(".qif")


def add_options(p) -> None:
    p.add_argument("--feature", metavar="NAME", help="a .qif part: the measured feature (FeatureName or id); "
                   "not needed when one feature has points")
    p.add_argument("--results", type=int, metavar="N", help="a .qif part: which MeasurementResults (from 1)")
    p.add_argument("--tool-radius-mm", type=float, metavar="R", help="a .qif part: the cutter's radius (mm)")
    p.add_argument("--part-frame", type=float, nargs=6, metavar=("X", "Y", "Z", "RX", "RY", "RZ"),
                   help="a .qif part: the part frame in the robot's base (mm, deg roll-pitch-yaw), or --best-fit")


def check_options(args, parts: list[str]) -> None:
    """Refuse, before any work, a QIF option without a .qif part, or a .qif part without its tool radius."""
    from stiffness.errors import ConfigError

    qif = [p for p in parts if is_qif(p)]
    given = [o for o, v in (("--feature", args.feature), ("--results", args.results),
                            ("--tool-radius-mm", args.tool_radius_mm), ("--part-frame", args.part_frame))
             if v is not None]
    if given and not qif:
        raise ConfigError(f"{given[0]}: only for a .qif part (a part CSV carries its own tool_radius_mm and "
                          "part_frame)")
    if qif and args.tool_radius_mm is None:
        raise ConfigError(f"{qif[0]}: a QIF part needs --tool-radius-mm R (QIF does not carry the cutter's radius)")
    if args.tool_radius_mm is not None:
        check_number("--tool-radius-mm", args.tool_radius_mm, "mm", above=0.0, at_most=500.0)
    if args.results is not None and args.results < 1:
        raise ConfigError(f"--results {args.results}: must be 1 or more")
    for v in args.part_frame or []:
        check_number("--part-frame", v, "mm and deg")


def read_any(path: str, args) -> tuple:
    """The part file as a `PartMeasurement` (QIF by its name, .qif in any case; the part CSV otherwise), and the
    features of a QIF file left out because their points cannot be read (`QifLeftOut`; none for a CSV)."""
    from stiffness.data.part_points import read_part

    if not is_qif(path):
        return read_part(path), []
    from stiffness.data.qif_part import read_qif_part
    from stiffness.kinematics.robot import PoseConfig

    frame = None
    if args.part_frame is not None:
        frame = PoseConfig(xyz_mm=args.part_frame[:3], rpy_deg=args.part_frame[3:]).matrix()
    part, note, left_out = read_qif_part(path, args.tool_radius_mm, frame, args.feature, args.results)
    print(f"note: {path}: {note}", file=sys.stderr)
    return part, left_out


def register_features(ps) -> None:
    f = ps.add_parser("features", help="list the measured features of a QIF results file")
    f.add_argument("file", help="a QIF 3 results file (.qif)")
    f.add_argument("--results", type=int, metavar="N", help="which MeasurementResults (from 1)")
    f.add_argument("--json", action="store_true", help='print {"features": [...], "left_out": [...]} as JSON')
    f.set_defaults(func=run_features)


def run_features(args) -> int:
    from stiffness.data.qif_part import feature_rows, read_qif

    qif = read_qif(args.file, args.results)
    rows = feature_rows(qif)
    if args.json:
        print_json({"features": rows, "left_out": [x.to_dict() for x in qif.left_out]})
        return 0

    def mm(v):
        return "-" if v is None else f"{v:.4f}"

    print(f"{'name':16s} {'id':>6s} {'type':10s} {'points':>6s} {'compensated':>11s} {'units':6s} "
          f"{'diameter_mm':>12s} {'reported_mm':>12s}")
    for r in rows:
        print(f"{r['name']:16s} {r['id']:>6s} {r['type']:10s} {r['points']:6d} {r['compensated']!s:>11s} "
              f"{r['units']:6s} {mm(r.get('diameter_mm')):>12s} {mm(r.get('reported_diameter_mm')):>12s}"
              + (f"  ({r['note']})" if r.get("note") else ""))
    for x in qif.left_out:
        print(x.text(args.file))
    return 0
