"""`stiffcomp plc-library -o DIR`: write the PLC's side of the contract as TwinCAT 3 sources and PLCopen XML
(docs/plc.md), from the contract and the register map the config names.

The config is read as `stiffcomp run --check` reads it (`service.config.load_config`: every section with the
service's schema, the checks across sections, the files it names), so a misspelt section (``plcc:``) or the
register map passed as the config exits 2 naming the file and the key, instead of writing the default layout
the PLC would then use against the wrong registers."""

from __future__ import annotations

import ipaddress
import sys

from cell.plc import FORMATS, Endpoint, EndpointError, generate
from service.config import DEFAULT_CONFIG, load_config

from .common import check_output_folder, write_output

CHOICES = {"twincat": ("twincat",), "plcopen": ("plcopen",), "both": FORMATS}


def register(sub) -> None:
    p = sub.add_parser("plc-library", help="write the TwinCAT 3 library and the PLCopen XML of the PLC's side")
    p.add_argument("-o", "--output", required=True, help="folder to write twincat/ and plcopen/ into")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="service config naming the register map")
    p.add_argument("--format", choices=list(CHOICES), default="both", help="what to write (default both)")
    p.add_argument("--modbus-host", metavar="ADDRESS",
                   help="the service's IPv4 address as the PLC dials it (default plc.host, which is refused where it "
                        "is a bind address such as 0.0.0.0 or a host name)")
    p.add_argument("--main-block", choices=["ads", "modbus"], default="ads",
                   help="the block the example MAIN calls: FB_StiffComp over ADS (default) or FB_StiffCompModbus over "
                        "Modbus TCP (TF6250)")
    p.set_defaults(func=run)


def run(args) -> int:
    cfg = load_config(args.config)
    out = check_output_folder("-o", args.output)
    host, key = (args.modbus_host, "--modbus-host") if args.modbus_host else (cfg.plc.host, f"{args.config}: plc.host")
    endpoint = Endpoint(cfg.ads.net_id, cfg.ads.ams_port, host, cfg.plc.port, cfg.plc.device_id, key)
    try:
        files = generate(cfg.register_map(), endpoint, CHOICES[args.format], args.main_block)
    except EndpointError as e:
        if args.modbus_host:
            raise
        raise EndpointError(f"{e}: give the address the PLC reaches the service at with --modbus-host ADDRESS") from e
    for rel, data in files.items():
        write_output(out / rel, lambda p, data=data: p.write_bytes(data))
    print(f"plc-library: {len(files)} files in {out}")
    if ipaddress.ip_address(host).is_loopback:
        print(f"plc-library: note: the PLC dials {host} ({key}), which only a PLC on this machine reaches; for a "
              "PLC on another, give the address it reaches the service at with --modbus-host ADDRESS",
              file=sys.stderr)
    return 0
