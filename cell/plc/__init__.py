"""The PLC's side of the contract as PLC source: a TwinCAT 3 library and a PLCopen XML export.

`build(rmap, endpoint)` makes the library's objects from the contract (`plc_link.contract`) and a
register map; `generate(rmap, endpoint, formats)` renders them as files (relative path -> bytes):
``twincat/<object>.TcDUT|TcGVL|TcPOU`` and ``plcopen/StiffComp.xml``. The same inputs give the same
bytes (no time stamps, GUIDs from names). `stiffcomp plc-library` writes them; docs/plc.md says how
to use them on the PLC.
"""

from __future__ import annotations

from plc_link.register_map import RegisterMap

from . import plcopen, twincat
from .blocks import TASK, ads_block, command_bit_block, main_program, modbus_block
from .declarations import (
    Endpoint,
    EndpointError,
    bit_structs,
    block_struct,
    check_map,
    contract_gvl,
    settings_gvl,
    task_info_struct,
    task_state_enum,
)
from .model import Library

FORMATS = ("twincat", "plcopen")
PLCOPEN_FILE = "StiffComp.xml"

__all__ = ["FORMATS", "Endpoint", "EndpointError", "build", "generate"]


def build(rmap: RegisterMap, endpoint: Endpoint, transport: str = "ads") -> Library:
    """The library for ``rmap``; RegisterMapError where a map cannot be served by one request each way (or
    scales a count or a bit word), EndpointError where the service's Modbus address is not one a PLC dials.
    ``transport`` ("ads" or "modbus"): the block the example MAIN calls."""
    check_map(rmap)
    types = [block_struct(rmap, "to_plc"), block_struct(rmap, "from_plc"), task_info_struct(),
             task_state_enum(), *bit_structs()]
    return Library(types, [contract_gvl(rmap), settings_gvl(endpoint)],
                   [command_bit_block(), ads_block(rmap), modbus_block(rmap), main_program(rmap, transport)], TASK)


def generate(rmap: RegisterMap, endpoint: Endpoint, formats: tuple[str, ...] = FORMATS,
             transport: str = "ads") -> dict[str, bytes]:
    """Relative path -> contents of every file of ``formats``."""
    lib = build(rmap, endpoint, transport)
    out: dict[str, bytes] = {}
    if "twincat" in formats:
        out |= {f"twincat/{name}": data for name, data in twincat.files(lib).items()}
    if "plcopen" in formats:
        out[f"plcopen/{PLCOPEN_FILE}"] = plcopen.project(lib)
    return out
