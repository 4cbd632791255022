"""`stiffcomp status [--watch]`: a live view of the running service, read as a PLC reads it.

Reads the to_plc block over Modbus TCP and looks every value up by name through the register map's
codec (never by address), so it works against a service on another machine as well. Without
``--watch`` it prints one screen and exits (exit code 1 when the service does not answer); with
``--watch`` it redraws a few times a second, like ``top``, until Ctrl-C.
"""

from __future__ import annotations

import logging
import signal
import sys
import time

from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException
from rich.console import Console
from rich.live import Live

from plc_interface.register_map import RegisterMap
from service.config import DEFAULT_CONFIG, load_config

from .status_view import StatusView

POLL_S = 0.05          # readings for the exec-time samples and the rates
REDRAW_S = 0.25        # screen refreshes


def register(sub) -> None:
    p = sub.add_parser("status", help="live view of the running service (task, faults, wrench, corrections)")
    p.add_argument("--config", default=str(DEFAULT_CONFIG), help="service config (register map, plc.host/port)")
    p.add_argument("--host", default=None, help="the service's Modbus host (default: plc.host)")
    p.add_argument("--port", type=int, default=None, help="the service's Modbus port (default: plc.port)")
    p.add_argument("--watch", action="store_true", help="redraw a few times a second until Ctrl-C")
    p.set_defaults(func=run)


class BlockReader:
    """The to_plc block over Modbus, decoded into values by register name."""

    def __init__(self, rmap: RegisterMap, host: str, port: int, timeout_s: float = 0.5):
        block = rmap.blocks["to_plc"]
        self.codec = rmap.codecs["to_plc"]
        self.client = ModbusTcpClient(host, port=port, timeout=timeout_s, retries=0)
        self._read = (self.client.read_input_registers if block.table == "input_registers"
                      else self.client.read_holding_registers)
        self.where = f"{host}:{port}"

    def read(self) -> dict[str, float]:
        """Values by name; ConnectionError naming the address when the service does not answer."""
        if not self.client.connected and not self.client.connect():
            raise ConnectionError(f"no answer from the service at {self.where}")
        try:
            r = self._read(self.codec.start, count=self.codec.words)
        except ModbusException as e:
            self.client.close()
            raise ConnectionError(f"{self.where}: {e}") from e
        if r.isError():
            raise ConnectionError(f"{self.where} refused the read: {r}")
        return dict(zip(self.codec.names, self.codec.decode(r.registers)))

    def close(self) -> None:
        self.client.close()


def run(args) -> int:
    logging.getLogger("pymodbus").setLevel(logging.CRITICAL)     # the view shows a lost connection itself
    cfg = load_config(args.config)
    host = args.host or {"0.0.0.0": "127.0.0.1"}.get(cfg.plc.host, cfg.plc.host)
    reader = BlockReader(RegisterMap.from_yaml(cfg.resolve(cfg.plc.register_map)), host,
                         args.port or cfg.plc.port)
    view = StatusView(f"modbus {reader.where}")
    try:
        return watch(reader, view) if args.watch else once(reader, view)
    finally:
        reader.close()


def poll(reader: BlockReader, view: StatusView) -> bool:
    try:
        view.update(reader.read(), time.monotonic())
        return True
    except ConnectionError as e:
        view.failed(str(e))
        return False


def once(reader: BlockReader, view: StatusView) -> int:
    """Two readings REDRAW_S apart (for the rates), printed once."""
    if not poll(reader, view):
        print(f"stiffcomp status: {view.error}", file=sys.stderr)
        return 1
    time.sleep(REDRAW_S)
    poll(reader, view)
    Console().print(view.render())
    return 0


def watch(reader: BlockReader, view: StatusView) -> int:
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
