"""`stiffcomp model add MODEL EFFECT [--joint N] -o NEW.yaml` and `stiffcomp model effects`."""

from __future__ import annotations

from stiffness.effects import EFFECTS
from stiffness.model.edit import add_effect
from stiffness.model.stiffness_model import StiffnessModel

from .common import write_output


def register(sub) -> None:
    p = sub.add_parser("model", help="edit a model: add an effect, list the effect library")
    msub = p.add_subparsers(dest="model_command", metavar="ACTION", required=True)
    a = msub.add_parser("add", help="add a library effect to a model")
    a.add_argument("model", help="model YAML")
    a.add_argument("effect", choices=sorted(EFFECTS), help="effect name")
    a.add_argument("--joint", "--link", type=int, dest="joint", help="joint 1..6, or the link for an effect placed on a link (`model effects` lists where each goes)")
    a.add_argument("--preload", choices=["identify"],
                   help="identify the joint's static torque in `stiffcomp fit` (masses wrong or missing: "
                        "the model's preload entry, docs/effects.md)")
    a.add_argument("-o", "--output", required=True, help="where to write the new model YAML")
    a.set_defaults(func=run_add)
    e = msub.add_parser("effects", help="list the effect library with each effect's equation")
    e.set_defaults(func=run_effects)


def run_add(args) -> int:
    model = StiffnessModel.from_yaml(args.model)
    preload = {"joint": args.joint} if args.preload == "identify" else None
    new = add_effect(model, args.effect, args.joint, preload=preload)
    header = (f"# {args.model} with {args.effect} added" + (f" at {args.joint}" if args.joint else "")
              + "; fit it with `stiffcomp fit`")
    write_output(args.output, lambda p: new.to_yaml(p, header))
    print(f"written: {args.output} ({args.effect} added; its parameters start at their defaults)")
    return 0


def run_effects(args) -> int:
    for name, cls in EFFECTS.items():
        where = f"{cls.location_key} {', '.join(map(str, cls.joints))}" if cls.per_joint else "global"
        print(f"{name:20s} {where:20s} {cls.equation}")
    return 0
