"""The flange accelerometer's part of the blocks: the box's process data in, its values counted and scaled into
the from_plc record (docs/accelerometer.md).

The inputs are those Beckhoff's EP3751 gives (EP3751-0160 and -0260 documentation, "Process data objects":
per axis "AI Acc X/Y/Z Inputs", a Value, INT, in mg per LSB at the factory setting, and a Status with "TxPDO
State", 1 while the value is invalid (a self test), and "TxPDO Toggle", inverted at each new value); MAIN
declares them AT %I*, for the I/O configuration to link to the box. Each call a new valid value (the toggle
changed, no state bit set) is counted into ``acc_samples`` and scaled by ``fAccScale`` into ``acc_x`` ..
``acc_z``; an invalid value is neither counted nor passed, so the last valid one stands. The block has these
inputs only where the map binds the contract's `plc_link.contract.ACCELEROMETER` values.
"""

from __future__ import annotations

from plc_link.contract import ACCELEROMETER
from plc_link.register_map import RegisterMap

from .declarations import encode, iec_type
from .model import BOOL, INT, REAL, Var
from .statements import Assign, If

BOX_INPUTS = (Var("nAccX", INT, comment="the box's AI Acc X Inputs Value (EP3751: mg/LSB at the factory setting)"),
              Var("nAccY", INT, comment="the box's AI Acc Y Inputs Value"),
              Var("nAccZ", INT, comment="the box's AI Acc Z Inputs Value"),
              Var("bAccToggle", BOOL, comment="the box's TxPDO Toggle (AI Acc X): inverted at each new value"),
              *(Var(f"bAccState{a}", BOOL, comment=f"the box's TxPDO State (AI Acc {a}): its value is invalid "
                    "(a self test)") for a in "XYZ"))
SCALE = Var("fAccScale", REAL, "0.00980665", "m/s2 per LSB of the box's values: 1 mg, the factory setting")


def has_accelerometer(rmap: RegisterMap) -> bool:
    """The map binds the accelerometer's values (all of them: `declarations.check_map` refuses some)."""
    return all(n in rmap.by_name for n in ACCELEROMETER)


def box_state(rmap: RegisterMap) -> tuple[Var, ...]:
    """The block's own variables for the box: the toggle at the last call, the values counted."""
    return (Var("bAccLastToggle", BOOL, comment="the box's toggle bit at the last call"),
            Var("nAccSamples", iec_type(rmap.by_name["acc_samples"]), comment="new valid values counted"))


def box_statements(rmap: RegisterMap) -> list:
    """A new valid value counted and scaled into the from_plc record; an invalid one left out (none without the
    accelerometer)."""
    if not has_accelerometer(rmap):
        return []
    by = rmap.by_name
    new = (Assign("nAccSamples", "nAccSamples + 1"),
           *(Assign(f"stFromPlc.acc_{a}", encode(by[f"acc_{a}"], f"INT_TO_REAL(nAcc{a.upper()}) * fAccScale"))
             for a in "xyz"))
    return [If("bAccToggle <> bAccLastToggle AND NOT (bAccStateX OR bAccStateY OR bAccStateZ)", new),
            Assign("bAccLastToggle", "bAccToggle"),
            Assign("stFromPlc.acc_samples", encode(by["acc_samples"], "nAccSamples"))]
