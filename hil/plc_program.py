"""The PLC program the HIL's virtual PLC runs: TwinCAT sources, the files `stiffcomp plc-library` writes for the
scenario's config and register map (`generate_program`), or an integrator's edited copy of them
(``stiffcomp hil circle --plc-program DIR``).

The virtual PLC binds the program as a cell's I/O mapping binds it, by name, in ``MAIN``:

* it writes ``aReferenceDeg`` (the path's joint references), ``aJointsDeg`` (the robot's joints), ``bEnable``
  and, where MAIN declares them, ``fPlanTimeS``, ``fPlanEngagement`` (the feedforward's plan) and
  ``nPayloadIndex``;
* it drives the robot with ``aCommandDeg``, and logs ``fbStiffComp.bAlive`` (the link) and
  ``fbStiffComp.stToPlc`` (the service's record as the program last read it).

A program without one of the names it needs is refused with the name and the folder (`PROGRAM_NAMES`). The
scenario's ``plc.service_timeout_ms`` and ``plc.max_rate_deg_s``, where given, are written into
``GVL_StiffCompSettings.tServiceTimeout`` and ``MAIN.fMaxRateDegPerS`` before the first cycle.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from pathlib import Path

from cell.plc import Endpoint, generate
from plc_link.register_map import RegisterMap
from st_runtime import Runtime, StError, f32, load

from .errors import HilError

SUFFIXES = (".TcPOU", ".TcDUT", ".TcGVL")
PROGRAM_NAMES = ("aReferenceDeg", "aJointsDeg", "aCommandDeg", "bEnable", "fbStiffComp")
BLOCK_NAMES = ("bAlive", "stToPlc")


@dataclass(frozen=True)
class ProgramFile:
    path: Path
    sha256: str


class PlcProgram:
    """The TwinCAT sources of ``folder`` (or of its ``twincat/`` sub-folder, as `stiffcomp plc-library` writes)."""

    def __init__(self, folder: str | Path):
        folder = Path(folder)
        src = folder / "twincat" if (folder / "twincat").is_dir() else folder
        if not src.is_dir():
            raise HilError(f"--plc-program {folder}: no such folder")
        paths = sorted(p for p in src.iterdir() if p.suffix in SUFFIXES)
        if not paths:
            raise HilError(f"--plc-program {folder}: no TwinCAT sources ({', '.join(SUFFIXES)}) in {src}")
        self.folder = src
        self.files = [ProgramFile(p, hashlib.sha256(p.read_bytes()).hexdigest()) for p in paths]

    def summary(self, dialled=()) -> dict:
        """What the run's summary says of the program: its folder, each file with its sha256, and the addresses
        it ``dialled`` (`hil.cell_network.CellNetwork.dialled`, as a pass's log keeps them)."""
        return {"folder": str(self.folder), "files": {f.path.name: f.sha256 for f in self.files},
                "dialled": sorted(str(d) for d in dialled)}

    def start(self, network, cycle_ms: int, service_timeout_ms: float | None = None,
              max_rate_deg_s: float | None = None):
        """(runtime, MAIN): the program loaded on a runtime whose requests go over ``network``, with the
        scenario's settings where it gives them (module docstring); `HilError` naming the file and line where the runtime
        refuses it, or the name MAIN lacks."""
        runtime = Runtime(network, cycle_ms=cycle_ms)
        try:
            machine = load([f.path for f in self.files], runtime)
            main = machine.instance("MAIN")
            if service_timeout_ms is not None:
                machine.namespace["G_GVL_StiffCompSettings"].tServiceTimeout = round(service_timeout_ms)
            if max_rate_deg_s is not None:
                main.fMaxRateDegPerS = f32(max_rate_deg_s)
        except (StError, KeyError, AttributeError) as e:
            raise HilError(f"the PLC program in {self.folder} cannot run: {e}") from e
        missing = [n for n in PROGRAM_NAMES if not hasattr(main, n)]
        missing += [f"fbStiffComp.{n}" for n in BLOCK_NAMES if "fbStiffComp" not in missing
                    and not hasattr(getattr(main, "fbStiffComp", None), n)]
        if missing:
            raise HilError(f"the PLC program in {self.folder}: MAIN has no {', '.join(missing)} (the virtual PLC "
                           "binds these names, hil/plc_program.py)")
        return runtime, main


def generate_program(rmap: RegisterMap, port: int, unit_id: int, folder: Path) -> PlcProgram:
    """Write the TwinCAT library `stiffcomp plc-library --main-block modbus` writes for ``rmap``, dialling the
    service at 127.0.0.1:``port``, into ``folder``/twincat; the program."""
    files = generate(rmap, Endpoint(modbus_host="127.0.0.1", modbus_port=port, unit_id=unit_id,
                                    host_setting="the HIL's service"), ("twincat",), "modbus")
    for rel, data in files.items():
        (folder / rel).parent.mkdir(parents=True, exist_ok=True)
        (folder / rel).write_bytes(data)
    return PlcProgram(folder)
