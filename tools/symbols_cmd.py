"""`stiffcomp symbols [--json]`: print the ADS symbols the service offers (docs/ads.md)."""

from __future__ import annotations

import json

from plc_link.ads import symbols_from_map
from service.config import DEFAULT_CONFIG, load_config


def register(sub) -> None:
    p = sub.add_parser("symbols", help="print the ADS symbols (GVL_Comp.*, task info)")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="service config naming the register map")
    p.add_argument("--json", action="store_true", help="machine-readable list of symbols")
    p.set_defaults(func=run)


def run(args) -> int:
    cfg = load_config(args.config)
    symbols = symbols_from_map(cfg.register_map())
    if args.json:
        print(json.dumps([s.as_dict() for s in symbols], indent=2))
        return 0
    print("# ADS symbols; %MB (0x4020) lays over the Modbus words, see docs/ads.md")
    print(f"{'name':<50} {'type':<6} {'group':>6} {'offset':>6} {'size':>4}  writable")
    for s in symbols:
        print(f"{s.name:<50} {s.type_name:<6} {s.group:#06x} {s.offset:>6} {s.size:>4}  "
              f"{'yes' if s.writable else 'no'}")
    return 0
