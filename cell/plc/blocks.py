"""The library's blocks: ``FB_StiffComp`` (ADS, Tc2_System), ``FB_StiffCompModbus`` (Modbus TCP, TF6250's
Tc2_ModbusSrv), ``FB_StiffCompCommandBit`` (a tare or reset bit delivered through the writes) and the
example ``MAIN``.

Both blocks do the same each call, in this order (docs/plc.md, "The block's state table"):

1. build the from_plc record: the command word (enable as a level; tare and reset each a pulse from its
   input's rising edge, held until a write that carried it has ended without an error, then clear as
   long: `COMMAND_BIT_BODY`), the PLC heartbeat (+1 every call), the joints, the payload index and whatever
   else the map binds, each scaled as its register says; where the map binds the accelerometer, the box's
   values (`cell.plc.accelerometer`);
2. write it (one request covering the block; a new one starts when the last has ended);
3. read the to_plc record, keeping the last good copy; the call that takes an answer starts the next request;
4. note whether the service's heartbeat *and* cycle count moved since the last good read (the first good
   read counts as a move); the link is alive unless they stood still for ``tServiceTimeout`` or the last
   read failed (the table in docs/plc.md, which the HIL's virtual PLC follows);
5. decode the status and fault words (as WORD: IEC's AND takes bit strings); ``bValid`` is the link alive,
   the service running, no fault, not stopped and every joint's correction finite (``bCorrectionInvalid``
   otherwise); the correction is the service's (scaled back to degrees) while valid, else zero.

Each body is one named template (`BLOCK_BODY`, `COMMAND_BIT_BODY`, `MAIN_BODY`); what depends on the map is
built as statements (`statements`) and rendered into it. Only the requests differ between the two blocks
(`Requests`: `ADS`, `modbus`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from plc_link.contract import Fault, Status, TaskState
from plc_link.register_map import Register, RegisterMap

from .accelerometer import BOX_INPUTS, SCALE, box_state, box_statements, has_accelerometer
from .declarations import (
    CONTRACT,
    FAULT_BITS,
    FROM_PLC,
    SETTINGS,
    STATUS_BITS,
    TASK_STATE,
    TO_PLC,
    bit_type,
    camel,
    decode,
    encode,
    iec_type,
    plc_type,
)
from .model import BOOL, JOINTS_REAL, REAL, TIME, UDINT, Derived, Elementary, Pou, Task, Var, VarList
from .statements import Assign, Call, Case, Pin, render

JOINTS = range(1, 7)
COMMAND_BIT = Derived("FB_StiffCompCommandBit")
TASK = Task("PlcTask", 1.0, 20, "MAIN")     # priority 20 as TwinCAT's PlcTask; 1 ms, the paper's cycle


@dataclass(frozen=True)
class Requests:
    """How a block reaches the service: its read and write blocks, their execute, busy and error pins, and the
    pins each request is called with."""

    how: str
    read_fb: str
    write_fb: str
    execute_read: str
    execute_write: str
    busy: str
    error: str
    error_id: str
    read_pins: tuple[Pin, ...]
    write_pins: tuple[Pin, ...]


def _ads_pins(offset: str, length: str, buffer: Pin) -> tuple[Pin, ...]:
    return (Pin("NETID", f"{SETTINGS}.sAmsNetId"), Pin("PORT", f"{SETTINGS}.nAmsPort"),
            Pin("IDXGRP", f"{CONTRACT}.ADS_IGRP"), Pin("IDXOFFS", f"{CONTRACT}.{offset}"),
            Pin("LEN", f"{CONTRACT}.{length}"), buffer, Pin("TMOUT", f"{SETTINGS}.tRequestTimeout"))


# Tc2_System's ADSREAD and ADSWRITE (Beckhoff, TwinCAT 3 PLC Lib: Tc2_System): a rising edge of READ/WRITE
# starts the request, BUSY is TRUE until it ends, then ERR and ERRID tell how
ADS = Requests("ADS (Tc2_System: ADSREAD, ADSWRITE)", "ADSREAD", "ADSWRITE", "READ", "WRITE", "BUSY", "ERR", "ERRID",
               _ads_pins("ADS_IOFFS_TO_PLC", "CB_TO_PLC", Pin("DESTADDR", "ADR(stReadBuffer)")),
               _ads_pins("ADS_IOFFS_FROM_PLC", "CB_FROM_PLC", Pin("SRCADDR", "ADR(stWriteBuffer)")))


def _modbus_pins(tag: str, buffer: Pin) -> tuple[Pin, ...]:
    return (Pin("sIPAddr", f"{SETTINGS}.sModbusHost"), Pin("nTCPPort", f"{SETTINGS}.nModbusPort"),
            Pin("nUnitID", f"{SETTINGS}.nUnitId"), Pin("nQuantity", f"{CONTRACT}.MB_WORDS_{tag}"),
            Pin("nMBAddr", f"{CONTRACT}.MB_ADDR_{tag}"), Pin("cbLength", f"{CONTRACT}.CB_{tag}"), buffer,
            Pin("tTimeout", f"{SETTINGS}.tRequestTimeout"))


def modbus(rmap: RegisterMap) -> Requests:
    """TF6250's requests (Tc2_ModbusSrv: FB_MBReadInputRegs, FC4, or FB_MBReadRegs, FC3, as the map's to_plc
    table says; FB_MBWriteRegs, FC16); a rising edge of bExecute starts one, bBusy while it runs."""
    fc4 = rmap.blocks["to_plc"].table == "input_registers"
    return Requests("Modbus TCP (TF6250, Tc2_ModbusSrv: FB_MBReadInputRegs or FB_MBReadRegs, FB_MBWriteRegs)",
                    "FB_MBReadInputRegs" if fc4 else "FB_MBReadRegs", "FB_MBWriteRegs", "bExecute", "bExecute", "bBusy",
                    "bError", "nErrId", _modbus_pins("TO_PLC", Pin("pDestAddr", "ADR(stReadBuffer)")),
                    _modbus_pins("FROM_PLC", Pin("pSrcAddr", "ADR(stWriteBuffer)")))


@dataclass(frozen=True)
class Input:
    """An input of the blocks that the map may bind: the register it fills, the variable, what it means."""

    register: str
    var: str
    comment: str


OPTIONAL_INPUTS = (Input("payload_index", "nPayloadIndex", "the payload set to use (gravity.payloads index)"),
                   Input("plan_time_s", "fPlanTimeS", "the program's time in the feedforward's plan, s"),
                   Input("plan_engagement", "fPlanEngagement", "the engagement (0..1) planned ahead"))


def _bits(r: Register, field: str) -> str:
    return f"{iec_type(r).name}_TO_{bit_type(r).name}({field})"


BLOCK_BODY = """\
// 1. the from_plc record: enable as a level; tare and reset each a pulse from its input's rising edge, held
//    until a write that carried it has ended without an error, then clear as long (FB_StiffCompCommandBit)
nCommand := 0;
IF bEnable THEN nCommand := nCommand OR {contract}.CMD_ENABLE; END_IF
IF fbTare.bOut THEN nCommand := nCommand OR {contract}.CMD_TARE; END_IF
IF fbReset.bOut THEN nCommand := nCommand OR {contract}.CMD_RESET; END_IF
nPlcHeartbeat := nPlcHeartbeat + 1;
{from_plc}

// 2. write it: a new request starts when the last one has ended, with the record as it is then
bWriteStarted := NOT fbWrite.{busy};
IF bWriteStarted THEN stWriteBuffer := stFromPlc; END_IF
{write_call}
bWriteEnded := NOT fbWrite.{busy};
IF bWriteEnded THEN
    bWriteError := fbWrite.{error};
    IF bWriteError THEN nErrorId := fbWrite.{error_id}; END_IF
    fbWrite({execute_write} := FALSE);
END_IF
{command_bits}

// 3. read the to_plc record, keeping the last good copy; the call that takes an answer starts the next
//    request (a falling, then a rising edge of {execute_read}), so that one is under way every cycle
{read_call}
bNewData := FALSE;
IF NOT fbRead.{busy} THEN
    bReadError := fbRead.{error};
    IF bReadError THEN
        nErrorId := fbRead.{error_id};
    ELSE
        stToPlc := stReadBuffer;
        bNewData := TRUE;
    END_IF
    fbRead({execute_read} := FALSE);
{read_again}
END_IF
bError := bReadError OR bWriteError;
IF NOT bError THEN nErrorId := 0; END_IF

// 4. the service is alive while its heartbeat and cycle count both move (the first good read counts
// as a move) and the last read did not fail
IF bNewData AND (NOT bSeen OR (stToPlc.heartbeat <> nLastHeartbeat
        AND stToPlc.cycle_count <> nLastCycleCount)) THEN
    nLastHeartbeat := stToPlc.heartbeat;
    nLastCycleCount := stToPlc.cycle_count;
    bSeen := TRUE;
    tonStale(IN := FALSE);
END_IF
tonStale(IN := TRUE, PT := {settings}.tServiceTimeout);
bAlive := bSeen AND NOT tonStale.Q AND NOT bReadError;

// 5. decode the words; the correction only while valid. A correction that is not finite is refused: a NaN
//    fails every comparison and an infinity the bound (Beckhoff, Tc2_Utilities RealIsNaN), no call needed
{decode}
{correction}
bCorrectionInvalid := FALSE;
FOR i := 1 TO 6 DO
    IF NOT (aServiceDeg[i] >= -3.4E38 AND aServiceDeg[i] <= 3.4E38) THEN
        bCorrectionInvalid := TRUE;
    END_IF
END_FOR
bValid := bAlive AND stStatus.bRunning AND NOT stStatus.bFaulted AND nFaultWord = 0 AND NOT stStatus.bStopped
    AND NOT bCorrectionInvalid;
IF bValid THEN
    aCorrectionDeg := aServiceDeg;
ELSE
{zero}
END_IF
"""

COMMAND_BIT_BODY = """\
// A rising edge of bIn asks for one pulse; edges while one is delivered make one more after it.
// Each phase (set, then clear) lasts tMin at least and until a write request loaded in it has ended
// without an error: the service, which acts on the bit's rising edge, has then had the bit in its
// registers, and the clear between two pulses too, however long the writes take.
rtIn(CLK := bIn);
IF rtIn.Q THEN bPending := TRUE; END_IF
IF bLoaded THEN bInFlight := TRUE; END_IF
IF bEnded THEN
    IF bInFlight AND bOk THEN bCarried := TRUE; END_IF
    bInFlight := FALSE;
END_IF
tonPhase(IN := TRUE, PT := tMin);
IF tonPhase.Q AND bCarried AND (bOut OR bPending) THEN
    bOut := NOT bOut;
    IF bOut THEN bPending := FALSE; END_IF
    bCarried := FALSE;
    bInFlight := FALSE;
    tonPhase(IN := FALSE);
END_IF
bBusy := bOut OR bPending;
"""

MAIN_BODY = """\
// The block in a cyclic task: the correction reaches the references through a rate limit, and goes
// back to zero at the same rate when the service stops being valid. The step follows the task's own
// cycle time (TwinCAT's task info: CycleTime in 100 ns).
fCycleTimeS := UDINT_TO_REAL(TwinCAT_SystemInfoVarList._TaskInfo[GETCURTASKINDEXEX()].CycleTime) * 1.0E-7;
// With bResetOnRecovery the link's coming back (bAlive rising, the first contact too) asks for one reset:
// the faults the loss caused in the service are cleared, and one whose cause persists trips again.
rtAlive(CLK := fbStiffComp.bAlive);
{call}
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

MAIN_BLOCKS = {"ads": "FB_StiffComp", "modbus": "FB_StiffCompModbus"}


def _from_plc(rmap: RegisterMap) -> list:
    by = rmap.by_name
    out = [Assign("stFromPlc.command_word", f"{bit_type(by['command_word']).name}_TO_"
                  f"{iec_type(by['command_word']).name}(nCommand)"),
           Assign("stFromPlc.plc_heartbeat", "nPlcHeartbeat")]
    out += [Assign(f"stFromPlc.q{i}", encode(by[f"q{i}"], f"aJointsDeg[{i}]")) for i in JOINTS]
    out += [Assign(f"stFromPlc.{i.register}", encode(by[i.register], i.var)) for i in OPTIONAL_INPUTS
            if i.register in by]
    return out + box_statements(rmap)


def _command_bits() -> list:
    wrote = (Pin("bLoaded", "bWriteStarted"), Pin("bEnded", "bWriteEnded"), Pin("bOk", "NOT bWriteError"),
             Pin("tMin", f"{SETTINGS}.tPulse"))
    return [Call("fbTare", (Pin("bIn", "bTare"), *wrote)), Call("fbReset", (Pin("bIn", "bReset"), *wrote))]


def _decode(rmap: RegisterMap) -> list:
    by = rmap.by_name
    out = [Assign("nStatusWord", _bits(by["status_word"], "stToPlc.status_word")),
           Assign("nFaultWord", _bits(by["fault_word"], "stToPlc.fault_word"))]
    out += [Assign(f"stStatus.b{camel(s.name)}", f"(nStatusWord AND {CONTRACT}.STATUS_{s.name}) <> 0") for s in Status]
    out += [Assign(f"stFaults.b{camel(f.kind)}", f"(nFaultWord AND {CONTRACT}.FAULT_{f.name}) <> 0") for f in Fault]
    if "task_state" in by:          # an enum is not assigned from an integer in IEC: one branch per state
        out.append(Case("stToPlc.task_state", tuple((int(s), (Assign("eTaskState", f"{TASK_STATE.name}.{s.name}"),))
                                                    for s in TaskState)))
    return out


def _interface(rmap: RegisterMap, req: Requests) -> tuple[VarList, ...]:
    by = rmap.by_name
    optional = [Var(i.var, plc_type(by[i.register]), comment=i.comment) for i in OPTIONAL_INPUTS if i.register in by]
    acc = has_accelerometer(rmap)
    if acc:
        optional += [*BOX_INPUTS, SCALE]
    inputs = (Var("bEnable", BOOL, comment="apply the correction (level)"),
              Var("bTare", BOOL, comment="rising edge: tare the sensor"),
              Var("bReset", BOOL, comment="rising edge: reset the latched faults whose cause is gone"),
              Var("aJointsDeg", JOINTS_REAL, comment="actual joint positions, deg"), *optional)
    outputs = (Var("bValid", BOOL, comment="the correction may be applied: the service runs, has no fault, and "
                   "its heartbeat and cycle count advance"),
               Var("aCorrectionDeg", JOINTS_REAL, comment="joint corrections to add to the references "
                   "while bValid, else 0, deg"),
               Var("bCorrectionInvalid", BOOL, comment="the service's correction is not finite (NaN or an "
                   "infinity): refused, bValid is FALSE"),
               Var("bAlive", BOOL, comment="the service's heartbeat and cycle count moved within tServiceTimeout, "
                   "and the last read did not fail"),
               Var("stStatus", STATUS_BITS, comment="status_word, decoded"),
               Var("stFaults", FAULT_BITS, comment="fault_word, decoded"),
               Var("nStatusWord", bit_type(by["status_word"])), Var("nFaultWord", bit_type(by["fault_word"])),
               *((Var("eTaskState", TASK_STATE),) if "task_state" in by else ()),
               Var("bError", BOOL, comment="the last read or write failed"),
               Var("nErrorId", UDINT, comment=f"the error of the last failed request ({req.error_id}), 0 when "
                   "both the last read and write succeeded"),
               Var("stToPlc", TO_PLC, comment="the last good read, every register as the map carries it (raw)"))
    local = (Var("fbRead", Derived(req.read_fb)), Var("fbWrite", Derived(req.write_fb)),
             Var("fbTare", COMMAND_BIT), Var("fbReset", COMMAND_BIT), Var("tonStale", Derived("TON")),
             Var("stReadBuffer", TO_PLC), Var("stFromPlc", FROM_PLC), Var("stWriteBuffer", FROM_PLC),
             Var("nCommand", bit_type(by["command_word"])), Var("nPlcHeartbeat", iec_type(by["plc_heartbeat"])),
             Var("nLastHeartbeat", iec_type(by["heartbeat"])), Var("nLastCycleCount", iec_type(by["cycle_count"])),
             Var("bSeen", BOOL), Var("bNewData", BOOL), Var("bReadError", BOOL), Var("bWriteError", BOOL),
             Var("bWriteStarted", BOOL, comment="a write request starts this cycle"),
             Var("bWriteEnded", BOOL, comment="the write request ended this cycle"),
             Var("aServiceDeg", JOINTS_REAL, comment="the service's correction, deg (scaled back)"),
             Var("i", Elementary("INT")),
             *(box_state(rmap) if acc else ()))
    return (VarList("VAR_INPUT", inputs), VarList("VAR_OUTPUT", outputs), VarList("VAR", local))


def function_block(rmap: RegisterMap, name: str, req: Requests) -> Pou:
    by = rmap.by_name
    body = BLOCK_BODY.format(
        contract=CONTRACT, settings=SETTINGS, busy=req.busy, error=req.error, error_id=req.error_id,
        execute_read=req.execute_read, execute_write=req.execute_write,
        from_plc=render(_from_plc(rmap)), command_bits=render(_command_bits()),
        write_call=render([Call("fbWrite", (*req.write_pins, Pin(req.execute_write, "TRUE")))]),
        read_call=render([Call("fbRead", (*req.read_pins, Pin(req.execute_read, "TRUE")))]),
        read_again=render([Call("fbRead", (*req.read_pins, Pin(req.execute_read, "TRUE")))], 1),
        decode=render(_decode(rmap)),
        correction=render([Assign(f"aServiceDeg[{i}]", decode(by[f"correction_q{i}"], f"stToPlc.correction_q{i}"))
                           for i in JOINTS]),
        zero=render([Assign(f"aCorrectionDeg[{i}]", "0.0") for i in JOINTS], 1))
    return Pou(name, "FUNCTION_BLOCK", _interface(rmap, req), body,
               f"The PLC's side of the stiffcomp contract over {req.how}; call it every cycle of a fast task "
               "(docs/plc.md). Generated by `stiffcomp plc-library`, do not edit.")


def ads_block(rmap: RegisterMap) -> Pou:
    return function_block(rmap, "FB_StiffComp", ADS)


def modbus_block(rmap: RegisterMap) -> Pou:
    return function_block(rmap, "FB_StiffCompModbus", modbus(rmap))


def command_bit_block() -> Pou:
    inputs = (Var("bIn", BOOL, comment="rising edge: one pulse of the bit"),
              Var("bLoaded", BOOL, comment="a write request started this cycle with bOut in its record"),
              Var("bEnded", BOOL, comment="the write request ended this cycle"),
              Var("bOk", BOOL, comment="... without an error"),
              Var("tMin", TIME, comment="each phase, set and clear, lasts at least this long"))
    outputs = (Var("bOut", BOOL, comment="the command bit to write"),
               Var("bBusy", BOOL, comment="a pulse is set or asked for"))
    local = (Var("rtIn", Derived("R_TRIG")), Var("bPending", BOOL), Var("bInFlight", BOOL),
             Var("bCarried", BOOL), Var("tonPhase", Derived("TON")))
    return Pou(COMMAND_BIT.name, "FUNCTION_BLOCK",
               (VarList("VAR_INPUT", inputs), VarList("VAR_OUTPUT", outputs), VarList("VAR", local)),
               COMMAND_BIT_BODY, "A tare or reset bit of command_word, held until the service has had it "
               "(docs/plc.md). Generated by `stiffcomp plc-library`, do not edit.")


def main_program(rmap: RegisterMap, transport: str = "ads") -> Pou:
    """The example task's program: the block of ``transport`` (`MAIN_BLOCKS`) and the inputs the map binds."""
    by = rmap.by_name
    optional = [i for i in OPTIONAL_INPUTS if i.register in by]
    acc = BOX_INPUTS if has_accelerometer(rmap) else ()
    local = (Var("fbStiffComp", Derived(MAIN_BLOCKS[transport])), Var("bEnable", BOOL), Var("bTare", BOOL),
             Var("bReset", BOOL),
             Var("bResetOnRecovery", BOOL, "TRUE", "reset the service's faults once each time the link comes back"),
             Var("rtAlive", Derived("R_TRIG")),
             Var("aJointsDeg", JOINTS_REAL, comment="from the axes, deg"),
             *(Var(i.var, plc_type(by[i.register]), comment=i.comment) for i in optional),
             *(replace(v, at="%I*") for v in acc),
             Var("aReferenceDeg", JOINTS_REAL, comment="the axes' references before correction, deg"),
             Var("aCommandDeg", JOINTS_REAL, comment="the references with the correction, deg"),
             Var("aAppliedDeg", JOINTS_REAL, comment="the correction applied, after the rate limit"),
             Var("fMaxRateDegPerS", REAL, "2.0", "how fast the applied correction may change, deg/s"),
             Var("fCycleTimeS", REAL, comment="this task's cycle time, s (from the task info)"),
             Var("fStep", REAL), Var("fTarget", REAL), Var("i", Elementary("INT")))
    pins = (Pin("bEnable", "bEnable"), Pin("bTare", "bTare"),
            Pin("bReset", "bReset OR (bResetOnRecovery AND rtAlive.Q)"), Pin("aJointsDeg", "aJointsDeg"),
            *(Pin(i.var, i.var) for i in optional), *(Pin(v.name, v.name) for v in acc))
    body = MAIN_BODY.format(call=render([Call("fbStiffComp", pins)]))
    return Pou(TASK.program, "PROGRAM", (VarList("VAR", local),), body,
               f"Example: {MAIN_BLOCKS[transport]} in a cyclic task, its correction rate-limited onto the axes' "
               "references")
