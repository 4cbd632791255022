"""An IEC 61131-3 Structured Text runtime for TwinCAT sources: it runs the PLC program the cell loads, in the
HIL's virtual PLC and in the tests (docs/plc.md, "The ST runtime").

`load(paths, runtime)` parses the ``.TcPOU``, ``.TcDUT`` and ``.TcGVL`` files with blark (TwinCAT's
structured-text grammar) and translates each POU once into a Python function over its variables
(`translate`, `expressions`); `Machine.instance("MAIN")` is the program, whose ``body()`` is one cycle.

The subset is what the generated library and an integrator's edits of it use: elementary types, arrays,
structs (laid out as TwinCAT lays them), enums, global variable lists, IF, CASE, FOR, assignments, block calls
with named inputs, the conversions X_TO_Y, LIMIT, MIN, MAX, ABS, ADR, the standard blocks TON, TP and R_TRIG
(`blocks`) and Beckhoff's request blocks ADSREAD, ADSWRITE and TF6250's Modbus blocks (`requests`). Anything
else is an `StError` naming the POU and line, never a silent no-op.

Time: the runtime's clock is ``Runtime.now_ms``, set by the caller before each cycle, never the wall clock;
the task's cycle time is ``Runtime.cycle_ms`` (TwinCAT's task info). Requests travel over the caller's
`requests.Network`.
"""

from .machine import Machine, Runtime, load
from .requests import Ended, Network, Transfer
from .values import StError, f32

__all__ = ["Ended", "Machine", "Network", "Runtime", "StError", "Transfer", "f32", "load"]
