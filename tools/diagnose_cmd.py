"""`stiffcomp diagnose MODEL DATA [--report DIR] [--json]`: name the physical effect a model lacks."""

from __future__ import annotations

import sys
from pathlib import Path

from stiffness.diagnose.discovery import diagnose
from stiffness.diagnose.report import build_report, to_dict

from .common import Progress, add_duplicates_option, load, print_json, write_output
from .fit_cmd import add_robust_option


def register(sub) -> None:
    p = sub.add_parser("diagnose", help="fit, show where the model fails, and name the missing effect")
    p.add_argument("model", help="model YAML")
    p.add_argument("data", help="measurement campaign (CSV or Parquet)")
    p.add_argument("--report", metavar="DIR", help="write an HTML report with plots into DIR")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--top", type=int, default=None, help="list only the best N candidates")
    add_robust_option(p)
    add_duplicates_option(p)
    p.set_defaults(func=run)


def run(args) -> int:
    model, data = load(args.model, args.data, args.keep_duplicates)
    progress = Progress("diagnose")
    d = diagnose(model, data, progress, robust=args.robust)
    progress.done()
    if args.report:
        report = build_report(d, args.model, args.data)
        path = write_output(Path(args.report) / "index.html", lambda p: report.write(p.parent))
        print(f"report: {path}", file=sys.stderr)
    if args.json:
        print_json(to_dict(d, args.top))
        return 0
    print(f"verdict: {d.verdict}")
    print(f"  {d.message}")
    print(f"  residual RMS {d.fit.rms_text()}; worst body "
          f"{d.worst['body']}, component {d.worst['component']}, configuration {d.worst['config']}, "
          f"load {d.worst['load_range']}")
    print(f"  {d.fit.outlier_text()}")
    if d.fit.unidentifiable:
        print("  not determined by the measured components: " + ", ".join(d.fit.unidentifiable))
    print("  candidates (best first):")
    for c in d.candidates[:args.top or 8]:
        where = f"{c.effect.location_key} {c.joint}" if c.joint is not None else "global"
        print(f"    {'*' if c.named else ' '} {c.name:20s} {where:8s} CV {100 * c.cv_improvement:5.1f} %  "
              f"dBIC {c.delta_bic:10.1f}  after {c.rms_position_mm_after:.4f} mm {c.rms_rotation_deg_after:.5f} deg")
    if d.best is not None:
        b = d.best
        loc = f" --joint {b.joint}" if b.joint is not None else ""
        loc += "".join(f" --{k} {v}" for k, v in b.add_options().items())
        print(f"  next: stiffcomp model add {args.model} {b.name}{loc} -o with_{b.name}.yaml")
    return 0
