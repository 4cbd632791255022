"""`stiffcomp status [--watch]`: a live view of the running service, read as a PLC reads it.

Reads the to_plc registers by name, never by address, so it works against a service on another
machine as well:

* over Modbus TCP (the block in one read, decoded by the register map's codec) when the service is
  a Modbus server (``plc.role: server``);
* over ADS otherwise (``plc.role: client`` or ``none``): the registers' ``GVL_Comp`` symbols in one
  sum read, with pyads, as a TwinCAT project reads them. ``--via`` chooses either.

From the config it reads only the ``plc``, ``ads``, ``monitoring`` and ``gravity`` (the payload sets' names)
sections (`service.config.read_sections`),
so a site config copied out of the container works from the host. The register map is the one the
config names; where that path does not exist here (a path inside the image), the shipped map, with
a note, or the one ``--register-map`` names.

Without ``--watch`` it prints one screen and exits (exit code 1 when the service does not answer,
2 when the config offers no way to read it); with ``--watch`` it redraws a few times a second, like
``top``, until Ctrl-C.
"""

from __future__ import annotations

import logging
import signal
import sys
import time
from pathlib import Path

from rich.console import Console
from rich.live import Live

from plc_link.register_map import RegisterMap
from service.config import DEFAULT_CONFIG, read_sections

from .block_reader import AdsReader, BlockReader
from .status_view import StatusView

POLL_S = 0.05          # readings for the exec-time samples and the rates
REDRAW_S = 0.25        # screen refreshes


def register(sub) -> None:
    p = sub.add_parser("status", help="live view of the running service (task, faults, wrench, corrections)")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="service config (register map; plc and ads addresses)")
    p.add_argument("--via", choices=("auto", "modbus", "ads"), default="auto",
                   help="modbus or ads (default: modbus when plc.role is server, else ads)")
    p.add_argument("--host", default=None, help="the service's host (default: plc.host or ads.host)")
    p.add_argument("--port", type=int, default=None, help="the service's Modbus or AMS/TCP port "
                   "(default: plc.port or ads.port)")
    p.add_argument("--register-map", default=None, metavar="FILE",
                   help="the register map (default: the config's plc.register_map, else the shipped one)")
    p.add_argument("--watch", action="store_true", help="redraw a few times a second until Ctrl-C")
    p.set_defaults(func=run)


SHIPPED_MAP = DEFAULT_CONFIG.parent / "registers.yaml"


def register_map_for(cfg, given: str | None) -> RegisterMap:
    """``--register-map``, else the config's map, else (a path that exists only inside the image) the
    shipped one, with a note on stderr."""
    if given is not None:
        cfg.plc.register_map = str(Path(given).resolve())
    elif not cfg.resolve(cfg.plc.register_map).exists():
        print(f"stiffcomp status: note: plc.register_map = {str(cfg.resolve(cfg.plc.register_map))!r} is not on "
              f"this machine (a path inside the container?); reading with the shipped map {SHIPPED_MAP} "
              "(--register-map FILE for another)", file=sys.stderr)
        cfg.plc.register_map = str(SHIPPED_MAP)
    return cfg.register_map()


def reader_for(cfg, via: str, host: str | None, port: int | None, register_map: str | None = None):
    """The reader ``--via`` asks for, and its protocol's name; ValueError naming the keys when the config
    serves neither protocol, or when pyads, which ADS needs, is missing."""
    if via == "auto":
        plain = cfg.plc.role == "server" and (not cfg.plc.tls.enabled or cfg.plc.tls.plain)
        via = "modbus" if plain else "ads" if cfg.ads.enabled else ""
        if not via:
            raise ValueError(f"plc.role is {cfg.plc.role}{' with TLS alone' if cfg.plc.role == 'server' else ''} "
                             "and ads.enabled is false: the service serves neither plain Modbus nor ADS to read "
                             "its status from (--via modbus --host H --port P reads another one)")
    rmap = register_map_for(cfg, register_map)
    local = {"0.0.0.0": "127.0.0.1"}
    if via == "modbus":
        return BlockReader(rmap, host or local.get(cfg.plc.host, cfg.plc.host), port or cfg.plc.port), via
    try:
        return AdsReader(rmap, host or local.get(cfg.ads.host, cfg.ads.host), port or cfg.ads.port,
                         cfg.ads.net_id, cfg.ads.ams_port), via
    except ValueError as e:
        raise ValueError(f"{e}; --via modbus reads a Modbus server") from None


def run(args) -> int:
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)     # the view shows a lost connection itself
    cfg = read_sections(args.config, "plc", "ads", "monitoring", "gravity")
    try:
        reader, via = reader_for(cfg, args.via, args.host, args.port, args.register_map)
    except ValueError as e:
        print(f"stiffcomp status: {args.config}: {e}", file=sys.stderr)
        return 2
    view = StatusView(f"{via} {reader.where}",
                      payload_names={k: p.name for k, p in cfg.gravity.payload_sets().items()})
    try:
        return watch(reader, view) if args.watch else once(reader, view)
    finally:
        reader.close()


def poll(reader: BlockReader | AdsReader, view: StatusView) -> bool:
    try:
        view.update(reader.read(), time.monotonic())
        return True
    except ConnectionError as e:
        view.failed(str(e))
        return False


def once(reader: BlockReader | AdsReader, view: StatusView) -> int:
    """Two readings REDRAW_S apart (for the rates), printed once."""
    if not poll(reader, view):
        print(f"stiffcomp status: {view.error}", file=sys.stderr)
        return 1
    time.sleep(REDRAW_S)
    poll(reader, view)
    Console().print(view.render())
    return 0


def watch(reader: BlockReader | AdsReader, view: StatusView) -> int:
    """Redraw every REDRAW_S until Ctrl-C or SIGTERM; exit code 0."""
    stop = []
    previous = signal.signal(signal.SIGTERM, lambda *_: stop.append(True))
    try:
        with Live(view.render(), auto_refresh=False, screen=False) as live:
            next_draw = time.monotonic()
            while not stop:
                poll(reader, view)
                if time.monotonic() >= next_draw:
                    live.update(view.render(), refresh=True)
                    next_draw += REDRAW_S
                time.sleep(POLL_S)
    except KeyboardInterrupt:
        pass
    finally:
        signal.signal(signal.SIGTERM, previous)
    return 0
