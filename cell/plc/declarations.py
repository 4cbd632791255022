"""The library's types and global lists, from the contract and the register map.

* ``ST_StiffCompToPlc`` / ``ST_StiffCompFromPlc``: each block's registers in address order, as the process
  image lays them (a gap between registers is a reserved ``ARRAY OF WORD``), so one ADS or Modbus read of
  the block's bytes lands on the struct. ``pack_mode 1`` is set where natural alignment would move a field
  or pad the end (then ``SIZEOF`` would no longer be the image's byte count).
* ``ST_StiffCompTaskInfo``: the task info the service serves at index group 0x4040.
* ``E_StiffCompTaskState``: `TaskState`. ``ST_StiffCompStatus`` / ``ST_StiffCompFaults``: one BOOL per bit.
* ``GVL_StiffCompContract`` (constants): every command, status and fault bit with the contract's value, and
  where each block lies (ADS index group and offset, byte count; Modbus address and word count).
* ``GVL_StiffCompSettings``: what an integrator edits (the service's AMS Net ID and port, its Modbus
  address, the timeouts).

And how a register's value meets the PLC's variable (`plc_type`, `encode`, `decode`): a REAL, scaled into and
out of an integer register where the map says so.
"""

from __future__ import annotations

import ipaddress
import itertools
import struct
from dataclasses import dataclass

import numpy as np

from io_base.errors import PlcError
from plc_link.ads.area import MB_GROUP, TASKINFO, TASKINFO_FIELDS, TASKINFO_GROUP, Layout
from plc_link.ads.symbols import IEC_TYPES
from plc_link.contract import ACCELEROMETER, VALUES, Command, Fault, Status, TaskState
from plc_link.errors import RegisterMapError
from plc_link.register_map import INT_RANGE, TYPES, Register, RegisterMap, struct_fields

from .model import (
    BOOL,
    BYTE,
    DWORD,
    REAL,
    TIME,
    UDINT,
    UINT,
    WORD,
    ArrayType,
    Derived,
    Elementary,
    Enum,
    Gvl,
    StringType,
    Struct,
    Type,
    Var,
    VarList,
)

TO_PLC, FROM_PLC = Derived("ST_StiffCompToPlc"), Derived("ST_StiffCompFromPlc")
TASK_INFO, TASK_STATE = Derived("ST_StiffCompTaskInfo"), Derived("E_StiffCompTaskState")
STATUS_BITS, FAULT_BITS = Derived("ST_StiffCompStatus"), Derived("ST_StiffCompFaults")
CONTRACT, SETTINGS = "GVL_StiffCompContract", "GVL_StiffCompSettings"
MODBUS_MAX_READ, MODBUS_MAX_WRITE = 125, 123      # registers in one FC3/FC4 read, one FC16 write
RECORDS = {"to_plc": TO_PLC, "from_plc": FROM_PLC}
BIT_WORDS = ("command_word", "status_word", "fault_word")
# TF6250's FB_MBReadRegs/FB_MBWriteRegs take the server's address as sIPAddr : STRING(15), a dotted IPv4
# address (Beckhoff, TF6250 manual, "FB_MBReadRegs"): the longest such text is 15 characters
HOST_LENGTH = 15


class EndpointError(PlcError):
    """The service's address as the config gives it is not one the PLC's Modbus client can dial."""


@dataclass(frozen=True)
class Endpoint:
    """The connection settings written as the GVL's defaults (from the service config in use)."""

    net_id: str = "127.0.0.1.1.1"
    ams_port: int = 851
    modbus_host: str = "127.0.0.1"
    modbus_port: int = 502
    unit_id: int = 1
    host_setting: str = "plc.host"      # where modbus_host came from, for the error that refuses it


def check_host(host: str, key: str) -> None:
    """EndpointError unless ``host`` (the setting ``key`` gave it) is an address TF6250 can dial: a dotted
    IPv4 address (at most `HOST_LENGTH` characters) that names one host, not a bind-all or multicast one."""
    try:
        addr = ipaddress.ip_address(host)
    except ValueError:
        addr = None
    if addr is None or addr.version != 4:
        why = "a host name" if addr is None else "an IPv6 address"
        raise EndpointError(f"{key} = {host!r} is {why}: the PLC's Modbus client (TF6250, sIPAddr : "
                            f"STRING({HOST_LENGTH})) dials a dotted IPv4 address")
    if addr.is_unspecified or addr.is_multicast or host == "255.255.255.255":
        raise EndpointError(f"{key} = {host!r} is a bind address (every interface), not one a PLC can dial")


def camel(name: str) -> str:
    """``sensor_timeout`` -> ``SensorTimeout`` (a bit's BOOL is ``b`` + this)."""
    return "".join(p.capitalize() for p in name.split("_"))


def hex16(value: int) -> str:
    return f"16#{value:04X}"


def iec_type(r: Register) -> Elementary:
    """The IEC type of register ``r``'s field (the ADS symbol's type)."""
    return Elementary(IEC_TYPES[r.type])


def bit_type(r: Register) -> Elementary:
    """The bit string a bit word is handled as: WORD for one register, DWORD for two (IEC 61131-3 takes AND,
    OR on BOOL and bit strings only, not on UINT)."""
    return WORD if r.count == 1 else DWORD


# -- a register's value in the PLC's variables (the blocks' statements) ------------------------------------
def real_literal(x: float) -> str:
    """``x`` as an IEC REAL literal (a point always; ``1.0E-05``, not ``1e-05``)."""
    text = repr(float(x))
    mantissa, _, exponent = text.partition("e")
    if "." not in mantissa:
        mantissa += ".0"
    return f"{mantissa}E{exponent}" if exponent else mantissa


def physical(r: Register) -> bool:
    """Whether the PLC handles register ``r`` as a REAL (the contract's value is a float32): an integer
    register then carries it scaled."""
    return VALUES[r.direction][r.name].type == "float32"


def plc_type(r: Register) -> Type:
    """The type of the PLC's variable for register ``r``'s value: REAL for a physical value, else the field's."""
    return REAL if physical(r) else iec_type(r)


def _inside(bound: int) -> float:
    """The REAL nearest ``bound`` on the side of zero (2147483647 is no REAL; 2147483520.0 is the one below)."""
    x = np.float32(bound)
    return float(x if abs(float(x)) <= abs(bound) else np.nextafter(x, np.float32(0)))


def real_bounds(code: str) -> tuple[float, float]:
    """The widest REAL range inside the integer type's range: a REAL outside it would overflow REAL_TO_*."""
    lo, hi = INT_RANGE[code]
    return _inside(lo), _inside(hi)


def encode(r: Register, value: str) -> str:
    """The expression that puts ``value`` (the PLC's variable) into register ``r``'s field: a REAL scaled,
    limited to the type's range and rounded (REAL_TO_*: IEC 61131-3 rounds) into an integer register, as the
    service decodes it (raw = value * scale, docs/register_map.md). A NaN ``value`` fails LIMIT's comparisons
    and leaves as the type's lower bound (docs/plc.md, "The ST runtime"), far outside every joint's limits,
    which the service refuses (``value_invalid``)."""
    if not physical(r) or r.type == "float32":
        return value
    lo, hi = real_bounds(TYPES[r.type][0])
    scaled = value if r.scale == 1.0 else f"{value} * {real_literal(r.scale)}"
    return f"REAL_TO_{iec_type(r).name}(LIMIT({real_literal(lo)}, {scaled}, {real_literal(hi)}))"


def decode(r: Register, field: str) -> str:
    """The expression that reads register ``r``'s value from its field ``field``: an integer register carrying
    a REAL as raw / scale."""
    if not physical(r) or r.type == "float32":
        return field
    real = f"{iec_type(r).name}_TO_REAL({field})"
    return real if r.scale == 1.0 else f"{real} / {real_literal(r.scale)}"


def _field(r: Register) -> Var:
    unit = f" [{r.unit}]" if r.unit else ""
    scale = f" (raw = value * {r.scale:g})" if r.scale != 1.0 else ""
    return Var(r.name, iec_type(r), comment=f"{r.description}{unit}{scale}".strip())


def block_struct(rmap: RegisterMap, direction: str) -> Struct:
    """The record of one block, its registers from the first one's address on, gaps reserved."""
    regs = [r for r in rmap.registers if r.direction == direction]
    fields, offset, natural = [], 0, True
    pos = regs[0].address
    for r in regs:
        if r.address > pos:
            n = r.address - pos
            fields.append(Var(f"reserved_{pos:04X}", ArrayType(1, n, WORD), comment="no register here"))
            offset += 2 * n
        size = 2 * r.count
        natural &= offset % size == 0
        fields.append(_field(r))
        offset += size
        pos = r.address + r.count
    widest = 2 * max(r.count for r in regs)
    natural &= offset % widest == 0
    table = regs[0].table.replace("_", " ")
    comment = (f"{direction}: {table} {hex16(regs[0].address)}..{hex16(pos - 1)} ({offset} bytes), one field per "
               "register of the map; generated by `stiffcomp plc-library`, do not edit")
    return Struct(RECORDS[direction].name, tuple(fields), comment, pack=not natural)


def task_info_struct() -> Struct:
    sizes = {at: struct.calcsize("<" + code) for code, at in struct_fields(TASKINFO.format)}
    fields, offset = [], 0
    for name, typ, at, source, _ in TASKINFO_FIELDS:
        if at > offset:
            fields.append(Var(f"reserved_{offset}", ArrayType(1, at - offset, BYTE)))
        fields.append(Var(name, Elementary(typ), comment=f"from {source}"))
        offset = at + sizes[at]
    if TASKINFO.size > offset:
        fields.append(Var(f"reserved_{offset}", ArrayType(1, TASKINFO.size - offset, BYTE)))
    return Struct(TASK_INFO.name, tuple(fields), "TwinCAT_SystemInfoVarList._TaskInfo[1] as the service serves it "
                  f"(index group {hex16(TASKINFO_GROUP)})", pack=True)


def bit_structs() -> list[Struct]:
    status = Struct(STATUS_BITS.name, tuple(Var(f"b{camel(s.name)}", BOOL, comment=f"status_word bit "
                                                f"{s.bit_length() - 1}") for s in Status), "status_word, bit by bit")
    faults = Struct(FAULT_BITS.name, tuple(Var(f"b{camel(f.kind)}", BOOL, comment=f"fault_word bit "
                                               f"{f.bit_length() - 1}") for f in Fault), "fault_word, bit by bit")
    return [status, faults]


def task_state_enum() -> Enum:
    return Enum(TASK_STATE.name, UINT, tuple((s.name, int(s), "") for s in TaskState), "task_state, as TwinCAT's")


def check_map(rmap: RegisterMap) -> None:
    """RegisterMapError where the map cannot be read or written as one block by the library's blocks, or binds
    the accelerometer's values only in part."""
    bound = [n for n in ACCELEROMETER if n in rmap.by_name]
    if bound and len(bound) < len(ACCELEROMETER):
        raise RegisterMapError(f"{rmap.source}: from_plc binds {', '.join(bound)} but not "
                               f"{', '.join(n for n in ACCELEROMETER if n not in bound)}: the accelerometer's values "
                               "go together (docs/register_map.md, \"The accelerometer\")")
    regs = [r for r in rmap.registers if r.direction == "from_plc"]
    for a, b in itertools.pairwise(regs):
        if b.address != a.address + a.count:
            raise RegisterMapError(f"{rmap.source}: from_plc: {b.name} at {b.address:#06x} leaves a gap after "
                                   f"{a.name}: FB_StiffComp writes the from_plc registers in one request, which "
                                   "must cover registers only")
    for direction, most in (("to_plc", MODBUS_MAX_READ), ("from_plc", MODBUS_MAX_WRITE)):
        words = _span(rmap, direction)[1]
        if words > most:
            raise RegisterMapError(f"{rmap.source}: {direction} spans {words} registers: one Modbus request "
                                   f"carries at most {most}")
    for r in rmap.registers:
        if r.scale != 1.0 and VALUES[r.direction][r.name].type != "float32":
            raise RegisterMapError(f"{rmap.source}: {r.direction}: {r.name}: scale = {r.scale:g}: a count, bit word "
                                   "or index takes scale 1 (the blocks compare and decode it as it is)")


def _span(rmap: RegisterMap, direction: str) -> tuple[Register, int]:
    regs = [r for r in rmap.registers if r.direction == direction]
    return regs[0], regs[-1].address + regs[-1].count - regs[0].address


def contract_gvl(rmap: RegisterMap) -> Gvl:
    word = {n: bit_type(rmap.by_name[n]) for n in BIT_WORDS}
    bits = [Var(f"CMD_{c.name}", word["command_word"], hex16(int(c)), "command_word") for c in Command]
    bits += [Var(f"STATUS_{s.name}", word["status_word"], hex16(int(s)), "status_word") for s in Status]
    bits += [Var(f"FAULT_{f.name}", word["fault_word"], hex16(int(f)), "fault_word") for f in Fault]
    layout = Layout(rmap)
    where = [Var("ADS_IGRP", UDINT, hex16(MB_GROUP), "%MB: the Modbus words end to end"),
             Var("ADS_IGRP_TASKINFO", UDINT, hex16(TASKINFO_GROUP), TASK_INFO.name),
             Var("ADS_CB_TASKINFO", UDINT, str(TASKINFO.size))]
    for direction, tag in (("to_plc", "TO_PLC"), ("from_plc", "FROM_PLC")):
        first, words = _span(rmap, direction)
        record = RECORDS[direction].name
        where += [Var(f"ADS_IOFFS_{tag}", UDINT, str(layout.mb_offset(first)), f"{record} in %MB"),
                  Var(f"CB_{tag}", UDINT, str(2 * words), f"bytes of {record}"),
                  Var(f"MB_ADDR_{tag}", WORD, hex16(first.address), f"Modbus {first.table}"),
                  Var(f"MB_WORDS_{tag}", WORD, str(words))]
    return Gvl(CONTRACT, (VarList("VAR_GLOBAL", tuple(bits + where), constant=True),),
               "The contract's bits and the register map's layout; generated by `stiffcomp plc-library`, do not "
               "edit")


def settings_gvl(end: Endpoint) -> Gvl:
    """The settings an integrator edits. The timeouts hold together: a request may take up to
    tRequestTimeout, so the service counts as lost only after longer than that without a move
    (tServiceTimeout), and the service's own watch on the PLC (faults.plc_heartbeat_timeout_ms, 200 ms
    shipped) is longer than one write may take."""
    check_host(end.modbus_host, end.host_setting)
    settings = (
        Var("sAmsNetId", StringType(23), f"'{end.net_id}'", "the service's AMS Net ID (ads.net_id)"),
        Var("nAmsPort", UINT, str(end.ams_port), "the service's AMS port (ads.ams_port)"),
        Var("sModbusHost", StringType(HOST_LENGTH), f"'{end.modbus_host}'",
            "the service's IPv4 address as the PLC reaches it (plc.host, or plc-library --modbus-host)"),
        Var("nModbusPort", UINT, str(end.modbus_port), "the service's Modbus TCP port (plc.port)"),
        Var("nUnitId", BYTE, str(end.unit_id), "Modbus unit id"),
        Var("tRequestTimeout", TIME, "T#100MS", "one ADS or Modbus request; keep it below tServiceTimeout"),
        Var("tServiceTimeout", TIME, "T#150MS",
            "bAlive drops when the service's heartbeat and cycle count stand still this long; longer than "
            "tRequestTimeout, so one slow request does not drop it"),
        Var("tPulse", TIME, "T#20MS", "a tare or reset bit stays set at least this long, and clear as long after"),
    )
    return Gvl(SETTINGS, (VarList("VAR_GLOBAL", settings),), "Connection settings: edit these for your site")
