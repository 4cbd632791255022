"""`stiffcomp payload POSES.csv`: mass, centre of gravity and bias from static poses (least squares).

POSES.csv has one row per static pose, the robot at rest and nothing touching the tool:
``q1_deg .. q6_deg, fx_N, fy_N, fz_N, mx_Nm, my_Nm, mz_Nm`` (the sensor's reading, sensor axes).
The poses must turn the sensor so that gravity points along three independent directions in its
frame. Prints the result as a ``gravity`` section for config/default.yaml (or JSON), or, with
``--write-entry N --name TEXT``, writes it as set N of the ``--config`` file's payload table
(``gravity.payloads``, `tools.payload_entry`, comments and number formats kept), which the PLC then
selects with ``payload_index`` = N. Without ``--config`` nothing is written: the shipped config is never
the site's file.

The sensor's orientation comes from the config's model as the service takes it: with a sensor
misalignment in the model, the sensor's real axes (`service.fast_effects.input_rotation`), so the
centre of gravity is found in the axes the service compensates gravity in.
"""

from __future__ import annotations

import json
import sys

import numpy as np

from service.config import DEFAULT_CONFIG, load_config
from service.fast_effects import input_rotation
from stiffness.kinematics.payload_identification import identify_payload, read_poses
from stiffness.model.stiffness_model import StiffnessModel

from .payload_entry import write_entry


def register(sub) -> None:
    p = sub.add_parser("payload", help="identify payload mass, centre of gravity and sensor bias")
    p.add_argument("poses", help="CSV with q1_deg..q6_deg and fx_N..mz_Nm, one static pose per row")
    p.add_argument("--config", default=None,
                   help="service config (robot and gravity vector; default: the shipped config/default.yaml, "
                        "which --write-entry never writes: it needs --config naming the site's file)")
    p.add_argument("--json", action="store_true", help="print JSON instead of a YAML snippet")
    p.add_argument("--write-entry", type=int, metavar="N", default=None,
                   help="write the result as set N (1..65535) of --config's gravity.payloads")
    p.add_argument("--name", default=None, help="the set's name (with --write-entry), e.g. 'spindle + D20 mill'")
    p.add_argument("--tcp-mm", type=float, nargs=3, default=None, metavar=("X", "Y", "Z"),
                   help="the tool's TCP in the flange frame, mm, recorded with the set (with --write-entry)")
    p.add_argument("--replace", action="store_true", help="overwrite set N if the table has it")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.write_entry is not None:
        refused = _refuse_write(args)
        if refused:
            print(f"stiffcomp payload: {refused}", file=sys.stderr)
            return 2
    cfg = load_config(args.config or DEFAULT_CONFIG)
    model = StiffnessModel.from_yaml(cfg.resolve(cfg.model.file))
    robot = model.robot
    data = read_poses(args.poses)
    F = robot.frames(np.radians(data[:, :6]))
    R = robot.sensor_pose(F)[:, :3, :3] @ input_rotation(model)
    fit = identify_payload(R, data[:, 6:], np.array(cfg.gravity.g_mps2))
    result = {"ok": bool(fit.ok), "message": fit.message, "mass_kg": float(fit.mass_kg), "cog_mm": (fit.cog_m * 1000).tolist(),
              "bias": fit.bias.tolist(), "residual_rms": fit.residual_rms.tolist(), "poses": len(data)}
    if args.write_entry is not None:
        return _write(args, fit, len(data))
    if args.json:
        print(json.dumps(result, indent=2))
    elif fit.ok:
        cog = ", ".join(f"{v:.1f}" for v in fit.cog_m * 1000)
        print(f"# stiffcomp payload {args.poses}: {len(data)} poses, residual RMS "
              f"{np.array2string(fit.residual_rms, precision=3)} (N, Nm)")
        print("gravity:")
        print(f"  tool: {{mass_kg: {fit.mass_kg:.3f}, cog_mm: [{cog}]}}   # everything the sensor carries")
        print(f"  bias: [{', '.join(f'{v:.3f}' for v in fit.bias)}]")
    else:
        print(f"stiffcomp payload: {fit.message}")
    return 0 if fit.ok else 1


def _refuse_write(args) -> str | None:
    """Why ``--write-entry`` cannot write (before any work), or None. The shipped (installed) config is
    never written unless ``--config`` names it: a copy under version control is the site's file."""
    if args.config is None:
        return (f"--write-entry needs --config FILE, the site config to write the set into; the shipped "
                f"{DEFAULT_CONFIG} is not written (copy it first: docs/commissioning.md, step 0)")
    if not args.name:
        return "--write-entry needs --name (the set's name the logs and the status show)"
    return None


def _write(args, fit, poses: int) -> int:
    """``--write-entry``: the fit as a set of the config's table (refused when the fit is not ok)."""
    if not fit.ok:
        print(f"stiffcomp payload: {fit.message}; nothing written to {args.config}", file=sys.stderr)
        return 1
    entry = {"index": args.write_entry, "name": args.name, "mass_kg": round(float(fit.mass_kg), 4),
             "cog_mm": [round(float(v) * 1000.0, 3) for v in fit.cog_m],
             "bias": [round(float(v), 4) for v in fit.bias]}
    if args.tcp_mm is not None:
        entry["tcp_mm"] = [float(v) for v in args.tcp_mm]
    print(write_entry(args.config, entry, args.replace))
    print(f"# {poses} poses, residual RMS {np.array2string(fit.residual_rms, precision=3)} (N, Nm); the PLC "
          f"selects it with payload_index = {args.write_entry}")
    return 0
