"""`stiffcomp kcart`: the Cartesian stiffness at the TCP, from a model or directly from TCP data."""

from __future__ import annotations

import numpy as np

from stiffness.errors import ConfigError
from stiffness.model.cartesian import identify_cartesian, tcp_stiffness, tcp_wrench_and_deflection

from .common import add_duplicates_option, load, print_json
from .torques_cmd import static_torques, torque_dict, torque_table


def register(sub) -> None:
    p = sub.add_parser("kcart", help="Cartesian stiffness K (Eq. 1) at the TCP")
    p.add_argument("model", help="model YAML")
    p.add_argument("--q", nargs=6, type=float, metavar="Q", help="joint angles in deg")
    p.add_argument("--data", help="identify K directly from the campaign's TCP rows, per configuration (Eq. 15)")
    p.add_argument("--json", action="store_true")
    add_duplicates_option(p)
    p.set_defaults(func=run)


def run(args) -> int:
    model, data = load(args.model, args.data, args.keep_duplicates)
    out = {}
    if args.q is not None:
        try:
            out["model"] = {"q_deg": args.q, "K": tcp_stiffness(model, np.array(args.q))}
        except ValueError as e:
            raise ConfigError(f"--q: {e}") from e
        torques = static_torques(model, args.q)
        out["model"]["static_torque_Nm"] = torque_dict(torques)
    if data is not None:
        out["identified"] = []
        for cfg in data.configs:
            sub = data.subset(data.config == cfg)
            W, dX = tcp_wrench_and_deflection(sub, model.robot)
            entry = {"config": cfg, "q_deg": sub.q_deg[0]}
            try:
                entry["K"] = identify_cartesian(W, dX)
            except ValueError as e:
                entry["error"] = str(e)
            out["identified"].append(entry)
    if not out:
        raise ConfigError("give --q Q1..Q6 (deg), --data DATA, or both")
    if args.json:
        print_json(out)
    else:
        np.set_printoptions(precision=4, suppress=False, linewidth=140)
        for key, val in out.items():
            for entry in val if isinstance(val, list) else [val]:
                where = f"{key} K at q = {np.asarray(entry['q_deg'])} deg"
                if "K" in entry:
                    print(f"{where} (N/m, N/rad; Nm/m, Nm/rad):\n{entry['K']}")
                else:
                    print(f"{where}: refused: {entry['error']}")
        if args.q is not None:
            print("static joint torques tau_s there (Nm, no payload; `stiffcomp torques` adds one):")
            print(torque_table(model, torques))
    return 0
