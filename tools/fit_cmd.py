"""`stiffcomp fit MODEL DATA -o FITTED.yaml [--json]`: identify a model's parameters."""

from __future__ import annotations

import sys

import numpy as np

from stiffness.effects.joint_spring import COMPONENTS, JointSpring
from stiffness.fit.identify import fit
from stiffness.fit.result import FitResult

from .common import Progress, add_duplicates_option, load, print_json, write_output


def register(sub) -> None:
    p = sub.add_parser("fit", help="identify a model's parameters from a measurement campaign")
    p.add_argument("model", help="model YAML (e.g. config/models/kr125_6dof.yaml)")
    p.add_argument("data", help="measurement campaign (CSV, or Parquet with pyarrow)")
    p.add_argument("-o", "--output", help="write the fitted model YAML here")
    p.add_argument("--json", action="store_true", help="print the result as JSON")
    p.add_argument("--nonnegative", action="store_true",
                   help="bound every compliance at >= 0 (bounded least squares); a warning names those "
                        "held at the bound")
    add_robust_option(p)
    add_duplicates_option(p)
    p.set_defaults(func=run)


def add_robust_option(p) -> None:
    """``--no-robust``: plain least squares, every row counts (shared by fit and diagnose)."""
    p.add_argument("--no-robust", dest="robust", action="store_false",
                   help="plain least squares: do not leave out rows judged gross errors (docs/measurement_format.md)")


def joint_stiffness(result: FitResult) -> list[dict]:
    """Per joint, the stiffness of each spring component (N/m or Nm/rad); None where absent.

    A negative compliance gives a negative stiffness, shown as it is (the fit's warnings name it); a
    compliance of exactly 0 (held at the bound by ``--nonnegative``) an infinite one.
    """
    table = [{"joint": j, **{c: None for c in COMPONENTS}} for j in range(1, 7)]
    for e in result.model.effects:
        if isinstance(e, JointSpring):
            for c, v in zip(e.components, e.theta):
                table[e.joint - 1][c] = 1.0 / v if v != 0 else float("inf")
    return table


def summary(result: FitResult) -> dict:
    params = []
    for e in result.model.effects:
        for p, v, s in zip(e.params, e.theta, e.std_error):
            params.append({"effect": e.name, "location": e.joint, "key": p.key, "unit": p.unit,
                           "value": v * p.yaml_factor, "std_error": s * p.yaml_factor})
    return {
        "rms_position_mm": result.rms_position_mm,
        "rms_rotation_deg": result.rms_rotation_deg,
        "joint_stiffness": joint_stiffness(result),
        "parameters": params,
        "undetermined": result.undetermined,
        "unidentifiable": result.unidentifiable,
        "outliers": result.outliers(),
        "noise_estimate": {"position_mm": result.sigma[0] if _measured(result, 0) else None,
                           "rotation_deg": result.sigma[3] if _measured(result, 3) else None},
        "converged": result.converged,
        "warnings": result.warnings,
        "preload": result.preload,
        "preload_evidence": [e.to_dict() for e in result.preload_evidence],
    }


def _measured(result: FitResult, k: int) -> bool:
    return bool(np.isfinite(result.residual[:, k:k + 3]).any())


def run(args) -> int:
    model, data = load(args.model, args.data, args.keep_duplicates)
    progress = Progress("fit")
    progress(f"fitting {len(model.theta)} parameters to {len(data)} rows")
    result = fit(model, data, robust=args.robust, nonnegative=args.nonnegative, progress=progress)
    progress.done()
    if args.output:
        header = (f"# Fitted by `stiffcomp fit` to {args.data} ({len(data)} rows): residual RMS "
                  f"{result.rms_text()}")
        write_output(args.output, lambda p: result.model.to_yaml(p, header))
    if args.json:
        print_json(summary(result))
    else:
        print_text(result, args)
    for w in result.warnings:
        print(f"warning: {w}", file=sys.stderr)
    if not result.converged:
        print(f"warning: the fit did not converge: {result.message}", file=sys.stderr)
    return 0


def print_text(result: FitResult, args) -> None:
    print(f"fitted {args.model} to {args.data}")
    print(f"  residual RMS per component: {result.rms_text()}")
    print("  joint stiffness (N/m for x, y, z; Nm/rad for rx, ry, rz; - not in the model; "
          "< 0 a negative compliance, see the warning; inf held at 0 by --nonnegative):")
    print("  joint " + "".join(f"{c:>12}" for c in COMPONENTS))
    for row in joint_stiffness(result):
        cells = "".join(f"{row[c]:12.3g}" if row[c] is not None else f"{'-':>12}" for c in COMPONENTS)
        print(f"  {row['joint']:5d} {cells}")
    if result.unidentifiable:
        print("  not determined by the measured components (kept at the starting value): "
              + ", ".join(result.unidentifiable))
    for note in result.preload:
        print(f"  {note}")
    print("  " + result.outlier_text())
    if args.output:
        print(f"  written: {args.output}")
