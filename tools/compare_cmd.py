"""`stiffcomp compare MODEL [MODEL2] DATA [--report DIR] [--json]`: model against measurement, no fit."""

from __future__ import annotations

import math
import shlex
import sys

from stiffness.compare.comparison import METRICS, Comparison, compare
from stiffness.compare.report import GROUPS, build_report, change_text
from stiffness.errors import ConfigError
from stiffness.model.stiffness_model import StiffnessModel

from .common import add_duplicates_option, load, print_json


def register(sub) -> None:
    p = sub.add_parser(
        "compare", help="compare one or two models with a measurement campaign (no fitting)",
        description="Predict the campaign's deflections with each model as it is (no fitting) and report "
                    "RMS, max |error| and R² overall and by body, component, configuration and load "
                    "direction. With two models the second is compared with the first. See docs/compare.md.")
    p.add_argument("files", nargs="+", metavar="FILE", help="MODEL [MODEL2] DATA: one or two model YAMLs, then "
                                                             "the campaign (CSV, or Parquet with pyarrow)")
    p.add_argument("--report", metavar="DIR", help="write an HTML report with plots into DIR")
    p.add_argument("--json", action="store_true", help="print the metrics as JSON (docs/compare.md)")
    add_duplicates_option(p)
    p.set_defaults(func=run)


def run(args) -> int:
    if len(args.files) not in (2, 3):
        raise ConfigError(f"compare takes MODEL [MODEL2] DATA: got {len(args.files)} file(s)")
    *model_paths, data_path = args.files
    first, data = load(model_paths[0], data_path, args.keep_duplicates)
    models = [first, *(StiffnessModel.from_yaml(p) for p in model_paths[1:])]
    for m in models:
        problem = m.unphysical()
        if problem:
            print(f"warning: {m.source}: {problem}; compared as it is, but `stiffcomp run` refuses this model "
                  "(refit with `stiffcomp fit --nonnegative`)", file=sys.stderr)
    comp = compare(models, data)
    if args.json:
        print_json(comp.to_dict())
    else:
        print_text(comp)
    if args.report:
        command = "stiffcomp compare " + " ".join(shlex.quote(f) for f in args.files)
        try:
            index = build_report(comp, command).write(args.report)
        except OSError as e:
            raise ConfigError(f"--report {args.report}: cannot write the report: {e.strerror or e}") from e
        print(f"report: {index}", file=sys.stderr if args.json else sys.stdout)
    return 0


def _fmt(v: float) -> str:
    return "-" if math.isnan(v) else f"{v:.4g}"


def print_text(comp: Comparison) -> None:
    names = [m.name for m in comp.models]
    w = max(14, *(len(n) + 2 for n in names))
    print(f"compare on {comp.data.source}: {len(comp.data)} rows, {len(comp.data.configs)} configurations "
          "(predicted without fitting)")
    ch = comp.change()
    print(f"  {'':28}" + "".join(f"{n:>{w}}" for n in names) + (f"{'change':>10}" if ch else ""))
    for metric in METRICS:
        line = f"  {metric.label:28}" + "".join(f"{_fmt(m.metrics[metric.key]):>{w}}" for m in comp.models)
        if ch:
            line += f"{change_text(metric.key, ch[metric.key]) or '-':>10}"
        print(line)
    for group, what in GROUPS:
        print(f"  RMS by {what} (mm / deg):")
        for k in comp.models[0].metrics[group]:
            cells = "".join(f"{_fmt(m.metrics[group][k]['rms_position_mm']) + ' / ' + _fmt(m.metrics[group][k]['rms_rotation_deg']):>{w + 8}}"
                            for m in comp.models)
            print(f"    {k:10}{cells}")
    print("  RMS by component:")
    for c, g in comp.models[0].metrics["by_component"].items():
        cells = "".join(f"{_fmt(m.metrics['by_component'][c]['rms']):>{w}}" for m in comp.models)
        print(f"    {c:4} [{g['unit']:>3}]{cells}")
    text, kind = comp.verdict()
    print(f"{kind}: {text}")
