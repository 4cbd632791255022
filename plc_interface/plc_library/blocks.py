"""The library's blocks: ``FB_StiffComp`` (ADS, Tc2_System), ``FB_StiffCompModbus`` (Modbus TCP, TF6250's
Tc2_ModbusSrv) and the example ``MAIN``.

Both blocks do the same each call, in this order (docs/plc.md, "The block's state table"):

1. build the from_plc record: the command word (enable as a level; tare and reset each a pulse of
   ``tPulse`` started by its input's rising edge), the PLC heartbeat (+1 every call), the joints, the
   payload index and whatever else the map binds;
2. write it (one request covering the block; a new one starts when the last has ended);
3. read the to_plc record (likewise), keeping the last good copy;
4. note whether the service's heartbeat *and* cycle count moved since the last good read (the first good
   read counts as a move); the link is alive unless they stood still for ``tServiceTimeout`` or the last
   read failed (the table in docs/plc.md, which the HIL's virtual PLC follows);
5. decode the status and fault words; ``bValid`` is the link alive, the service running, no fault and not
   stopped; the correction is the service's while valid, else zero.
Only the requests differ (`ADS` and `MODBUS` name their pins).
"""

from __future__ import annotations

from ..contract import Fault, Status
from ..register_map import RegisterMap
from .declarations import CONTRACT, FAULT_BITS, FROM_PLC, SETTINGS, STATUS_BITS, TASK_STATE, TO_PLC, camel
from .model import Pou, Var, VarList

JOINTS = range(1, 7)
ADS = {"read": "ADSREAD", "write": "ADSWRITE", "exe_read": "READ", "exe_write": "WRITE", "busy": "BUSY",
       "err": "ERR", "errid": "ERRID",
       "read_args": ("NETID := {S}.sAmsNetId", "PORT := {S}.nAmsPort", "IDXGRP := {C}.ADS_IGRP",
                     "IDXOFFS := {C}.ADS_IOFFS_TO_PLC", "LEN := {C}.CB_TO_PLC", "DESTADDR := ADR(stReadBuffer)",
                     "TMOUT := {S}.tRequestTimeout"),
       "write_args": ("NETID := {S}.sAmsNetId", "PORT := {S}.nAmsPort", "IDXGRP := {C}.ADS_IGRP",
                      "IDXOFFS := {C}.ADS_IOFFS_FROM_PLC", "LEN := {C}.CB_FROM_PLC", "SRCADDR := ADR(stWriteBuffer)",
                      "TMOUT := {S}.tRequestTimeout")}
_MB_COMMON = ("sIPAddr := {S}.sModbusHost", "nTCPPort := {S}.nModbusPort", "nUnitID := {S}.nUnitId")
MODBUS = {"write": "FB_MBWriteRegs", "exe_read": "bExecute", "exe_write": "bExecute", "busy": "bBusy",
          "err": "bError", "errid": "nErrId",
          "read_args": (*_MB_COMMON, "nQuantity := {C}.MB_WORDS_TO_PLC", "nMBAddr := {C}.MB_ADDR_TO_PLC",
                        "cbLength := {C}.CB_TO_PLC", "pDestAddr := ADR(stReadBuffer)", "tTimeout := {S}.tRequestTimeout"),
          "write_args": (*_MB_COMMON, "nQuantity := {C}.MB_WORDS_FROM_PLC", "nMBAddr := {C}.MB_ADDR_FROM_PLC",
                         "cbLength := {C}.CB_FROM_PLC", "pSrcAddr := ADR(stWriteBuffer)",
                         "tTimeout := {S}.tRequestTimeout")}
_INPUTS = {"payload_index": ("nPayloadIndex", "UINT", "the payload set to use (gravity.payloads index)"),
           "plan_time_s": ("fPlanTimeS", "REAL", "the program's time in the feedforward's plan, s"),
           "plan_engagement": ("fPlanEngagement", "REAL", "the engagement (0..1) planned ahead")}


def _call(fb: str, args: tuple[str, ...], extra: str) -> str:
    pins = ",\n    ".join(a.format(S=SETTINGS, C=CONTRACT) for a in (*args, extra))
    return f"{fb}(\n    {pins});"


def _interface(rmap: RegisterMap, pins: dict) -> tuple[VarList, ...]:
    optional = [_INPUTS[r.name] for r in rmap.registers if r.name in _INPUTS]
    inputs = (Var("bEnable", "BOOL", comment="apply the correction (level)"),
              Var("bTare", "BOOL", comment="rising edge: tare the sensor"),
              Var("bReset", "BOOL", comment="rising edge: reset the latched faults whose cause is gone"),
              Var("aJointsDeg", "ARRAY[1..6] OF REAL", comment="actual joint positions, deg"),
              *(Var(n, t, comment=c) for n, t, c in optional))
    outputs = (Var("bValid", "BOOL", comment="the correction may be applied: the service runs, has no fault, and "
                   "its heartbeat and cycle count advance"),
               Var("aCorrectionDeg", "ARRAY[1..6] OF REAL", comment="joint corrections to add to the references "
                   "while bValid, else 0, deg"),
               Var("bAlive", "BOOL", comment="the service's heartbeat and cycle count moved within tServiceTimeout, "
                   "and the last read did not fail"),
               Var("stStatus", STATUS_BITS, comment="status_word, decoded"),
               Var("stFaults", FAULT_BITS, comment="fault_word, decoded"),
               Var("nStatusWord", "UINT"), Var("nFaultWord", "UINT"),
               *((Var("eTaskState", TASK_STATE),) if "task_state" in rmap.by_name else ()),
               Var("bError", "BOOL", comment="the last read or write failed"),
               Var("nErrorId", "UDINT", comment=f"the error of the last failed request ({pins['errid']}), 0 when "
                   "both the last read and write succeeded"),
               Var("stToPlc", TO_PLC, comment="the last good read, every value"))
    read_fb = pins["read"]
    local = (Var("fbRead", read_fb), Var("fbWrite", pins["write"]), Var("tpTare", "TP"), Var("tpReset", "TP"),
             Var("tonStale", "TON"), Var("stReadBuffer", TO_PLC), Var("stFromPlc", FROM_PLC),
             Var("stWriteBuffer", FROM_PLC), Var("nCommand", "UINT"), Var("nPlcHeartbeat", "UINT"),
             Var("nLastHeartbeat", "UINT"), Var("nLastCycleCount", "UDINT"), Var("bSeen", "BOOL"),
             Var("bNewData", "BOOL"), Var("bReadError", "BOOL"), Var("bWriteError", "BOOL"))
    return (VarList("VAR_INPUT", inputs), VarList("VAR_OUTPUT", outputs), VarList("VAR", local))


def _command(rmap: RegisterMap) -> list[str]:
    c = CONTRACT
    lines = ["// 1. the from_plc record: enable as a level, tare and reset as pulses from their rising edges",
             f"tpTare(IN := bTare, PT := {SETTINGS}.tPulse);", f"tpReset(IN := bReset, PT := {SETTINGS}.tPulse);",
             "nCommand := 0;", f"IF bEnable THEN nCommand := nCommand OR {c}.CMD_ENABLE; END_IF",
             f"IF tpTare.Q THEN nCommand := nCommand OR {c}.CMD_TARE; END_IF",
             f"IF tpReset.Q THEN nCommand := nCommand OR {c}.CMD_RESET; END_IF",
             "nPlcHeartbeat := nPlcHeartbeat + 1;",
             "stFromPlc.command_word := nCommand;", "stFromPlc.plc_heartbeat := nPlcHeartbeat;"]
    lines += [f"stFromPlc.q{i} := aJointsDeg[{i}];" for i in JOINTS]
    lines += [f"stFromPlc.{r.name} := {_INPUTS[r.name][0]};" for r in rmap.registers if r.name in _INPUTS]
    return lines


def _requests(pins: dict) -> list[str]:
    b, e, eid = pins["busy"], pins["err"], pins["errid"]
    return ["", "// 2. write it: a new request starts when the last one has ended",
            f"IF NOT fbWrite.{b} THEN stWriteBuffer := stFromPlc; END_IF",
            _call("fbWrite", pins["write_args"], f"{pins['exe_write']} := TRUE"),
            f"IF NOT fbWrite.{b} THEN", f"    bWriteError := fbWrite.{e};",
            f"    IF bWriteError THEN nErrorId := fbWrite.{eid}; END_IF", f"    fbWrite({pins['exe_write']} := FALSE);",
            "END_IF", "", "// 3. read the to_plc record, keeping the last good copy",
            _call("fbRead", pins["read_args"], f"{pins['exe_read']} := TRUE"),
            "bNewData := FALSE;", f"IF NOT fbRead.{b} THEN", f"    bReadError := fbRead.{e};",
            "    IF bReadError THEN", f"        nErrorId := fbRead.{eid};", "    ELSE",
            "        stToPlc := stReadBuffer;", "        bNewData := TRUE;", "    END_IF",
            f"    fbRead({pins['exe_read']} := FALSE);", "END_IF",
            "bError := bReadError OR bWriteError;", "IF NOT bError THEN nErrorId := 0; END_IF"]


def _outputs(rmap: RegisterMap) -> list[str]:
    lines = ["", "// 4. the service is alive while its heartbeat and cycle count both move (the first good read counts",
             "// as a move) and the last read did not fail",
             "IF bNewData AND (NOT bSeen OR (stToPlc.heartbeat <> nLastHeartbeat",
             "        AND stToPlc.cycle_count <> nLastCycleCount)) THEN",
             "    nLastHeartbeat := stToPlc.heartbeat;", "    nLastCycleCount := stToPlc.cycle_count;",
             "    bSeen := TRUE;", "    tonStale(IN := FALSE);", "END_IF",
             f"tonStale(IN := TRUE, PT := {SETTINGS}.tServiceTimeout);",
             "bAlive := bSeen AND NOT tonStale.Q AND NOT bReadError;",
             "", "// 5. decode the words; the correction only while valid",
             "nStatusWord := stToPlc.status_word;", "nFaultWord := stToPlc.fault_word;"]
    lines += [f"stStatus.b{camel(s.name)} := (nStatusWord AND {CONTRACT}.STATUS_{s.name}) <> 0;" for s in Status]
    lines += [f"stFaults.b{camel(f.kind)} := (nFaultWord AND {CONTRACT}.FAULT_{f.name}) <> 0;" for f in Fault]
    if "task_state" in rmap.by_name:
        lines.append("eTaskState := stToPlc.task_state;")
    lines += [("bValid := bAlive AND stStatus.bRunning AND NOT stStatus.bFaulted AND nFaultWord = 0 "
               "AND NOT stStatus.bStopped;"), "IF bValid THEN"]
    lines += [f"    aCorrectionDeg[{i}] := stToPlc.correction_q{i};" for i in JOINTS]
    lines += ["ELSE"] + [f"    aCorrectionDeg[{i}] := 0.0;" for i in JOINTS] + ["END_IF"]
    return lines


def function_block(rmap: RegisterMap, name: str, pins: dict, how: str) -> Pou:
    body = "\n".join(_command(rmap) + _requests(pins) + _outputs(rmap)) + "\n"
    return Pou(name, "FUNCTION_BLOCK", _interface(rmap, pins), body,
               f"The PLC's side of the stiffcomp contract over {how}; call it every cycle of a fast task "
               "(docs/plc.md). Generated by `stiffcomp plc-library`, do not edit.")


def ads_block(rmap: RegisterMap) -> Pou:
    return function_block(rmap, "FB_StiffComp", ADS, "ADS (Tc2_System: ADSREAD, ADSWRITE)")


def modbus_block(rmap: RegisterMap) -> Pou:
    fc4 = rmap.blocks["to_plc"].table == "input_registers"
    pins = {**MODBUS, "read": "FB_MBReadInputRegs" if fc4 else "FB_MBReadRegs"}
    return function_block(rmap, "FB_StiffCompModbus", pins,
                          "Modbus TCP (TF6250, Tc2_ModbusSrv: FB_MBReadInputRegs or FB_MBReadRegs, FB_MBWriteRegs)")


MAIN_BODY = """\
// The block in a 1 ms task: the correction reaches the references through a rate limit, and goes
// back to zero at the same rate when the service stops being valid.
fbStiffComp(bEnable := bEnable, bTare := bTare, bReset := bReset, aJointsDeg := aJointsDeg);
fStep := fMaxRateDegPerS * fCycleTimeS;
FOR i := 1 TO 6 DO
    IF fbStiffComp.bValid THEN
        fTarget := fbStiffComp.aCorrectionDeg[i];
    ELSE
        fTarget := 0.0;
    END_IF
    aAppliedDeg[i] := aAppliedDeg[i] + LIMIT(-fStep, fTarget - aAppliedDeg[i], fStep);
    aCommandDeg[i] := aReferenceDeg[i] + aAppliedDeg[i];
END_FOR
"""


def main_program() -> Pou:
    local = (Var("fbStiffComp", "FB_StiffComp"), Var("bEnable", "BOOL"), Var("bTare", "BOOL"),
             Var("bReset", "BOOL"), Var("aJointsDeg", "ARRAY[1..6] OF REAL", comment="from the axes, deg"),
             Var("aReferenceDeg", "ARRAY[1..6] OF REAL", comment="the axes' references before correction, deg"),
             Var("aCommandDeg", "ARRAY[1..6] OF REAL", comment="the references with the correction, deg"),
             Var("aAppliedDeg", "ARRAY[1..6] OF REAL", comment="the correction applied, after the rate limit"),
             Var("fMaxRateDegPerS", "REAL", "2.0", "how fast the applied correction may change, deg/s"),
             Var("fCycleTimeS", "REAL", "0.001", "this task's cycle time, s"),
             Var("fStep", "REAL"), Var("fTarget", "REAL"), Var("i", "INT"))
    return Pou("MAIN", "PROGRAM", (VarList("VAR", local),), MAIN_BODY,
               "Example: FB_StiffComp in a 1 ms task, its correction rate-limited onto the axes' references")
