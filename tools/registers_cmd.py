"""`stiffcomp registers [--json]`: print the Modbus register map (docs/register_map.md)."""

from __future__ import annotations

import json

from service.config import DEFAULT_CONFIG, load_config


def register(sub) -> None:
    p = sub.add_parser("registers", help="print the Modbus register map")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="service config naming the map")
    p.add_argument("--json", action="store_true", help="machine-readable list of registers")
    p.set_defaults(func=run)


def run(args) -> int:
    cfg = load_config(args.config)
    rmap = cfg.register_map()
    if args.json:
        print(json.dumps(rmap.as_list(), indent=2))
        return 0
    print(f"# {rmap.source}: 32-bit values take two registers, low word first (TwinCAT layout)")
    print(f"{'name':<18} {'table':<18} {'address':>7} {'type':<8} {'count':>5} {'unit':<5} {'scale':>5}  direction")
    for r in rmap.registers:
        print(f"{r.name:<18} {r.table:<18} {r.address:#07x} {r.type:<8} {r.count:>5} {r.unit:<5} {r.scale:>5g}  "
              f"{r.direction}")
    return 0
