"""`stiffcomp torques MODEL --q Q1..Q6 [--payload-kg M --payload-cog-mm X Y Z]`: the static joint torques.

Per joint the arm's weight, the payload's, the balancer's share and their total tau_s (Nm), signed like
the external joint torque the model uses (W_i[rz], docs/effects.md "Static torque"). The masses and the
balancer come from the model's robot file (its ``inertial`` section or its URDF).
"""

from __future__ import annotations

import numpy as np

from stiffness.errors import ConfigError
from stiffness.robot import Robot
from stiffness.statics import Statics, StaticTorques

from .common import load, print_json

PARTS = ("arm", "payload", "balancer", "total")


def register(sub) -> None:
    p = sub.add_parser("torques", help="static joint torques (arm weight, payload, balancer) at a configuration")
    p.add_argument("model", help="model YAML (its robot file gives the masses)")
    p.add_argument("--q", nargs=6, type=float, required=True, metavar="Q", help="joint angles in deg")
    p.add_argument("--payload-kg", type=float, default=0.0, help="mass the sensor carries (spindle, tool), kg")
    p.add_argument("--payload-cog-mm", nargs=3, type=float, default=[0.0, 0.0, 0.0], metavar=("X", "Y", "Z"),
                   help="its centre of gravity in the sensor frame, mm")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=run)


def static_torques(robot: Robot, q_deg, payload_kg: float = 0.0, payload_cog_mm=(0.0, 0.0, 0.0)) -> StaticTorques:
    """tau_s at one configuration given on the command line; bad values become a ConfigError naming the option."""
    q_deg = np.asarray(q_deg, dtype=float)
    outside = np.flatnonzero(~robot.within_limits(q_deg)[0])
    if outside.size:
        i = outside[0]
        raise ConfigError(f"--q: joint {i + 1} = {q_deg[i]:g} deg is outside its limits "
                          f"[{robot.limits_deg[i, 0]:g}, {robot.limits_deg[i, 1]:g}] ({robot.source})")
    try:
        statics = Statics(robot, payload_kg, payload_cog_mm)
    except ValueError as e:
        raise ConfigError(f"--payload-kg/--payload-cog-mm: {e}") from e
    return statics(np.radians(q_deg))


def torque_table(robot: Robot, torques: StaticTorques) -> str:
    """The static torques at one configuration as a table, one line per joint (Nm)."""
    cols = [np.round(getattr(torques, p)[0], 1) + 0.0 for p in PARTS]       # + 0.0: no "-0.0"
    lines = ["joint " + "".join(f"{p:>11s}" for p in PARTS)]
    lines += [f"A{i + 1:<5d}" + "".join(f"{c[i]:11.1f}" for c in cols) for i in range(6)]
    if not robot.has_masses:
        lines.append(f"(no masses in {robot.source}: arm and balancer are zero; see docs/model_format.md)")
    elif robot.balancer is not None:
        lines.append(f"(balancer on joint {robot.balancer.joint} carries {robot.balancer.share:g} of the arm's torque there)")
    return "\n".join(lines)


def torque_dict(torques: StaticTorques) -> dict:
    return {p: getattr(torques, p)[0] for p in PARTS}


def run(args) -> int:
    model, _ = load(args.model)
    torques = static_torques(model.robot, args.q, args.payload_kg, args.payload_cog_mm)
    if args.json:
        print_json({"q_deg": args.q, "payload_kg": args.payload_kg, "payload_cog_mm": args.payload_cog_mm,
                    "static_torque_Nm": torque_dict(torques)})
        return 0
    payload = (f"; payload {args.payload_kg:g} kg at {np.asarray(args.payload_cog_mm).tolist()} mm (sensor frame)"
               if args.payload_kg else "")
    print(f"static joint torques tau_s at q = {np.asarray(args.q).tolist()} deg{payload}")
    print("(Nm, signed like the external joint torque W_i[rz]; gravity (0, 0, -9.81) m/s^2 in the base)")
    print(torque_table(model.robot, torques))
    return 0
