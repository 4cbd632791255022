"""`stiffcomp torques MODEL --q Q1..Q6 [--payload-kg M --payload-cog-mm X Y Z]`: the static joint torques.

Per joint the arm's weight, the payload's, the balancer's share, the model's identified correction (with
a ``preload`` list) and their total tau_s (Nm), signed like the external joint torque the model uses
(W_i[rz], docs/effects.md "Static torque"). The masses and the balancer come from the model's robot file
(its ``inertial`` section or its URDF). What it prints is what `fit` and the service use: a robot without
masses and without an identified preload models no static load, the payload's neither, and then it
says so instead of printing a torque nothing uses.
"""

from __future__ import annotations

import numpy as np

from stiffness.errors import ConfigError
from stiffness.kinematics.statics import Statics, StaticTorques, models_static_load
from stiffness.model.stiffness_model import StiffnessModel

from .common import load, print_json

PARTS = ("arm", "payload", "balancer", "total")
IDENTIFIED = "identified"       # the column of a model with an identified preload (before the total)


def register(sub) -> None:
    p = sub.add_parser("torques", help="static joint torques (arm weight, payload, balancer) at a configuration")
    p.add_argument("model", help="model YAML (its robot file gives the masses)")
    p.add_argument("--q", nargs=6, type=float, required=True, metavar="Q", help="joint angles in deg")
    p.add_argument("--payload-kg", type=float, default=0.0, help="mass the sensor carries (spindle, tool), kg")
    p.add_argument("--payload-cog-mm", nargs=3, type=float, default=[0.0, 0.0, 0.0], metavar=("X", "Y", "Z"),
                   help="its centre of gravity in the sensor frame, mm")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def static_torques(model: StiffnessModel, q_deg, payload_kg: float = 0.0,
                   payload_cog_mm=(0.0, 0.0, 0.0)) -> StaticTorques | None:
    """tau_s at one configuration given on the command line, as `fit` and the service form it (the
    model's identified preload included); None when the model has no static load (`not_modelled`). Bad
    values become a ConfigError naming the option."""
    robot = model.robot
    q_deg = np.asarray(q_deg, dtype=float)
    outside = np.flatnonzero(~robot.within_limits(q_deg)[0])
    if outside.size:
        i = outside[0]
        raise ConfigError(f"--q: joint {i + 1} = {q_deg[i]:g} deg is outside its limits "
                          f"[{robot.limits_deg[i, 0]:g}, {robot.limits_deg[i, 1]:g}] ({robot.source})")
    try:
        statics = Statics(robot, payload_kg, payload_cog_mm, preloads=model.preloads())
    except ValueError as e:
        raise ConfigError(f"--payload-kg/--payload-cog-mm: {e}") from e
    if not models_static_load(robot, model.preloads()):
        return None
    return statics(np.radians(q_deg))


def not_modelled(model: StiffnessModel, payload_kg: float = 0.0) -> str:
    """Why a model has no static torque, in words (for `static_torques`' None)."""
    payload = f"; a payload ({payload_kg:g} kg) is not modelled either" if payload_kg else ", a payload's neither"
    return (f"no static load modelled: {model.robot.source} has no masses and the model no identified preload, "
            f"so fit, compare and the service take tau_s = 0 (every effect at the external torque){payload}. "
            "Masses: docs/robot_format.md; why: docs/effects.md, \"Static torque\"")


def parts(torques: StaticTorques) -> tuple[str, ...]:
    """The columns to show: the identified correction only where the model has one."""
    return PARTS[:3] + ((IDENTIFIED,) if np.any(torques.identified) else ()) + PARTS[3:]


def torque_table(model: StiffnessModel, torques: StaticTorques | None) -> str:
    """The static torques at one configuration as a table, one line per joint (Nm)."""
    robot = model.robot
    if torques is None:
        return f"({not_modelled(model)})"
    shown = parts(torques)
    cols = [np.round(getattr(torques, p)[0], 1) + 0.0 for p in shown]       # + 0.0: no "-0.0"
    lines = ["joint " + "".join(f"{p:>11s}" for p in shown)]
    lines += [f"A{i + 1:<5d}" + "".join(f"{c[i]:11.1f}" for c in cols) for i in range(6)]
    if not robot.has_masses:
        lines.append(f"(no masses in {robot.source}: arm and balancer are zero; the identified correction "
                     "carries the static torque)")
    elif robot.balancer is not None:
        lines.append(f"(balancer on joint {robot.balancer.joint} carries {robot.balancer.share:g} of the arm's torque there)")
    return "\n".join(lines)


def torque_dict(torques: StaticTorques | None) -> dict:
    """The JSON form: each part's six torques (Nm); every part zero when no static load is modelled."""
    if torques is None:
        return {p: [0.0] * 6 for p in PARTS}
    return {p: getattr(torques, p)[0] for p in parts(torques)}


def run(args) -> int:
    model, _ = load(args.model)
    torques = static_torques(model, args.q, args.payload_kg, args.payload_cog_mm)
    if args.json:
        out = {"q_deg": args.q, "payload_kg": args.payload_kg, "payload_cog_mm": args.payload_cog_mm,
               "modelled": torques is not None, "static_torque_Nm": torque_dict(torques)}
        if torques is None:
            out["note"] = not_modelled(model, args.payload_kg)
        print_json(out)
        return 0
    if torques is None:
        print(f"static joint torques tau_s at q = {np.asarray(args.q).tolist()} deg: "
              f"{not_modelled(model, args.payload_kg)}")
        return 0
    payload = (f"; payload {args.payload_kg:g} kg at {np.asarray(args.payload_cog_mm).tolist()} mm (sensor frame)"
               if args.payload_kg else "")
    print(f"static joint torques tau_s at q = {np.asarray(args.q).tolist()} deg{payload}")
    print("(Nm, signed like the external joint torque W_i[rz]; gravity (0, 0, -9.81) m/s^2 in the base)")
    print(torque_table(model, torques))
    return 0
