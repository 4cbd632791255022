"""`stiffcomp plan MODEL --configurations N [--device optical6d|tracker] -o CAMPAIGN.yaml`: design a campaign."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np

from stiffness.errors import ConfigError
from stiffness.files.yaml_schema import dump_yaml
from stiffness.kinematics.robot import BODIES
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.plan.design import DEVICES, Device, Plan, plan
from stiffness.plan.simulate import LoadSpec, NoiseSpec, ReadingSpec

from .common import print_json, write_output


def register(sub) -> None:
    p = sub.add_parser("plan", help="choose the configurations that best determine a model (optimal design)",
                       description="Pick N configurations inside the joint limits that minimise the worst predicted "
                                   "relative standard error of the model's parameters for a measuring device and "
                                   "its noise (docs/plan.md). Writes a campaign YAML that `stiffcomp simulate` "
                                   "runs, with MODEL as the truth.")
    p.add_argument("model", help="model YAML to plan for (its values and noise are the planning assumptions)")
    p.add_argument("--configurations", "-n", type=int, required=True, help="how many configurations (N >= 1)")
    p.add_argument("--device", choices=sorted(DEVICES), default="optical6d",
                   help="optical6d: every body, 6 components; tracker: TCP position only")
    p.add_argument("--bodies", nargs="+", choices=BODIES, help="the bodies measured (default: the device's)")
    p.add_argument("--seed", type=int, default=0, help="seed of the candidate configurations")
    p.add_argument("--margin-deg", type=float, default=10.0, help="stay this far inside every joint limit")
    p.add_argument("-o", "--output", required=True, help="write the campaign YAML here")
    p.add_argument("--json", action="store_true", help="print the plan as JSON")
    p.set_defaults(func=run)


def run(args) -> int:
    if args.configurations < 1:
        raise ConfigError(f"--configurations = {args.configurations} must be at least 1")
    model = StiffnessModel.from_yaml(args.model)
    device = Device.named(args.device, model, args.bodies)
    tty = sys.stderr.isatty()

    def progress(msg: str) -> None:
        print(f"\r\033[Kplan: {msg}" if tty else f"plan: {msg}", end="" if tty else "\n", file=sys.stderr,
              flush=True)

    result = plan(model, device, args.configurations, args.seed, progress, margin_deg=args.margin_deg)
    if tty:
        print("\r\033[K", end="", file=sys.stderr)
    write_output(args.output, lambda p: p.write_text(campaign_yaml(result, model, device, args)))
    if args.json:
        print_json(to_dict(result, args))
    else:
        print_text(result, args)
    return 0


def campaign_yaml(result: Plan, model: StiffnessModel, device: Device, args) -> str:
    """The campaign file (docs/simulate.md): the plan's configurations, the protocol it assumed."""
    out = Path(args.output).resolve().parent
    truth = os.path.relpath(Path(args.model).resolve(), out)
    comps = [c for c, m in zip(("dx", "dy", "dz", "rx", "ry", "rz"), device.components) if m]
    doc = {
        "name": f"plan_{Path(args.model).stem}_{len(result.q_deg)}",
        "description": (f"planned by `stiffcomp plan` for {args.device}: worst predicted relative std error "
                        f"{result.criterion:.3g} (median of random sets of {len(result.q_deg)}: "
                        f"{result.random_median:.3g})"),
        "truth": truth,
        "seed": args.seed,
        "configurations": [{"name": f"P{i + 1}", "q_deg": [float(v) for v in q]} for i, q in enumerate(result.q_deg)],
        "loads": LoadSpec().model_dump(),
        "readings": ReadingSpec().model_dump(),
        "noise": NoiseSpec(position_mm=model.noise["position_mm"], rotation_deg=model.noise["rotation_deg"]).model_dump(),
        "bodies": device.bodies,
        "components": comps,
    }
    return "# Follow it in the lab; rehearse it with `stiffcomp simulate`.\n" + dump_yaml(doc, sort_keys=False, default_flow_style=None, width=120)


def to_dict(result: Plan, args) -> dict:
    return {
        "output": args.output, "device": args.device,
        "configurations": [{"name": f"P{i + 1}", "q_deg": q} for i, q in enumerate(result.q_deg.tolist())],
        "criterion": result.criterion, "random_median": result.random_median,
        "parameters": [{"parameter": lab, "predicted_std_error": se, "relative": rel, "of_interest": bool(i)}
                       for lab, se, rel, i in zip(result.labels, result.std_error, result.relative, result.interest)],
        "unidentifiable": result.unidentifiable,
    }


def print_text(result: Plan, args) -> None:
    print(f"plan for {args.model} with {args.device}: {len(result.q_deg)} configurations -> {args.output}")
    for i, q in enumerate(result.q_deg):
        print(f"  P{i + 1}: " + " ".join(f"{v:8.2f}" for v in q) + "  deg")
    print(f"  worst predicted relative std error {100 * result.criterion:.2f} % "
          f"(median of random sets of {len(result.q_deg)}: {100 * result.random_median:.2f} %)")
    print("  predicted std error of every parameter (SI; * = covered by the criterion):")
    for lab, se, rel, i in zip(result.labels, result.std_error, result.relative, result.interest):
        cell = "not identifiable" if not np.isfinite(se) else f"{se:10.3g}  ({100 * rel:.3g} %)"
        print(f"  {'*' if i else ' '} {lab:40s} {cell}")
    if result.unidentifiable:
        print("  not identifiable with this device: " + ", ".join(result.unidentifiable))
