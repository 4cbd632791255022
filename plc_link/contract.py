"""The PLC contract: every value that crosses to or from the PLC, declared once, addressed by name.

This module is the one owner of what the PLC sees: nothing else declares a bit or a value. It declares

* the command, status and fault bits (`Command`, `Status`, `Fault`) and the task state (`TaskState`);
* the values each way (`TO_PLC`, `FROM_PLC`): name, type, unit, meaning and, for the values the
  service publishes, where each comes from in the cycle (``source``);
* the named records the cycle produces and reads (`ToPlc`, `FromPlc`), whose fields are those names.

The register map (config/registers.yaml) binds names to Modbus addresses; the ADS symbols
(``GVL_Comp.<name>``) come from the same map. Nothing is matched by position: the image encodes a
record by name, and a map that names a value the contract does not declare is refused at start-up.

Adding a value for the PLC: declare it here (a `Value` whose ``source`` names the cycle quantity it
publishes) and bind it in the register map YAML. docs/architecture.md walks through an example.

The ``source`` of a to_plc value is a dotted path with an optional index, read once per cycle (by
operator getters compiled once, no ``eval``) from the cycle's records: ``task`` (the task's counters,
`TaskValues`) and ``signals`` (the signal path's outputs of the cycle, `service.signals.Signals`),
e.g. ``signals.correction[0]``.
"""

from __future__ import annotations

import enum
import re
from collections.abc import Callable
from dataclasses import dataclass
from operator import attrgetter, itemgetter
from typing import Any, NamedTuple

from .errors import ContractError


class Command(enum.IntFlag):
    """Bits of ``command_word`` (PLC -> service). Tare and reset act on their rising edge."""

    ENABLE = 0x1        # apply the correction while no fault is latched
    TARE = 0x2          # rising edge: the current external wrench becomes the new zero
    RESET = 0x4         # rising edge: clear latched faults whose cause is gone


COMMAND_BITS = int(Command.ENABLE | Command.TARE | Command.RESET)    # every other bit is undefined: a fault


class Status(enum.IntFlag):
    """Bits of ``status_word`` (service -> PLC)."""

    RUNNING = 0x1       # the cycle runs
    ACTIVE = 0x2        # the correction is applied (enabled, no fault, a sample seen, not stopping)
    FAULTED = 0x4       # a fault is latched (see fault_word)
    RAMPING = 0x8       # the correction is ramping to zero
    SENSOR_OK = 0x10    # a sample was seen and no sensor fault is latched
    PLC_SEEN = 0x20     # the PLC heartbeat has changed at least once
    STOPPED = 0x40      # the service stopped (the last value it publishes)
    TARE_REFUSED = 0x80  # the last tare request was refused (load above tare.max_force_N); cleared by a
                         # tare that is done or by a reset
    ACCELEROMETER_OK = 0x100  # the flange accelerometer's samples arrive (acc_samples moved within
                              # accelerometer.timeout_ms); clear: none configured, missing or frozen


class Fault(enum.IntFlag):
    """Bits of ``fault_word``: latched until a reset whose cause is gone. The names are the fault kinds
    that logs, metrics and `service.errors.SensorError.fault` use."""

    SENSOR_TIMEOUT = 1 << 0     # the sensor silent past faults.sensor_timeout_ms
    SENSOR_STATUS = 1 << 1      # the sensor's status word reports an error
    SENSOR_SATURATED = 1 << 2   # a gauge channel at the INT16 limit
    VALUE_INVALID = 1 << 3      # NaN, inf or out-of-range wrench, q or correction
    CAN_FRAME = 1 << 4          # a malformed or unknown CAN frame
    PLC_HEARTBEAT = 1 << 5      # the PLC heartbeat did not change within faults.plc_heartbeat_timeout_ms
    OVERRUN = 1 << 6            # faults.overrun_trip_count consecutive cycles overran their period
    JOINT_LIMITS = 1 << 7       # q outside the robot's joint limits
    IO_PROCESS = 1 << 8         # the I/O process died (it is restarted or the service stops)
    COMMAND_INVALID = 1 << 9    # command_word sets a bit the contract does not define
    PAYLOAD_INVALID = 1 << 10   # payload_index names no set of gravity.payloads (the set in use stays)

    @property
    def kind(self) -> str:
        """The fault's name as logs and metrics spell it (``sensor_timeout``)."""
        return (self.name or "").lower()

    @classmethod
    def from_kind(cls, kind: str) -> Fault:
        return cls[kind.upper()]

    @classmethod
    def spell(cls, word: int) -> list[str]:
        """The kinds set in a fault word, lowest bit first."""
        return [f.kind for f in cls if word & f]


FAULT_BITS: dict[str, int] = {f.kind: f.bit_length() - 1 for f in Fault}     # kind -> bit of fault_word

SENSOR_FAULTS = (Fault.SENSOR_TIMEOUT | Fault.SENSOR_STATUS | Fault.SENSOR_SATURATED | Fault.VALUE_INVALID
                 | Fault.CAN_FRAME)


class TaskState(enum.IntEnum):
    """``task_state``, as TwinCAT's task state."""

    INIT = 0
    RUN = 1
    STOP = 2


TYPES = ("uint16", "int16", "uint32", "int32", "float32")


@dataclass(frozen=True)
class Value:
    """One value of the contract.

    Parameters
    ----------
    name : the name the register map, the ADS symbols and the tests use
    type : the wire type, one of `TYPES`
    unit : physical unit ("" for counts and bit words)
    meaning : one line a PLC programmer reads
    source : for to_plc values, the cycle quantity it publishes (see the module docstring)
    required : the register map must bind it
    """

    name: str
    type: str
    unit: str
    meaning: str
    source: str = ""
    required: bool = True


_JOINTS = range(1, 7)
_WRENCH = ("fx", "fy", "fz", "mx", "my", "mz")
_DEFLECTION = ("dx", "dy", "dz", "rx", "ry", "rz")

TO_PLC: tuple[Value, ...] = (
    Value("heartbeat", "uint16", "", "+1 every cycle (wraps at 65535)", "task.heartbeat"),
    Value("status_word", "uint16", "", "Status bits: 0 running, 1 correction active, 2 faulted, 3 ramping, "
          "4 sensor ok, 5 PLC heartbeat seen, 6 stopped, 7 tare refused", "signals.status_word"),
    Value("fault_word", "uint16", "", "latched Fault bits", "signals.fault_word"),
    Value("task_state", "uint16", "", "TaskState: 0 init, 1 run, 2 stop", "task.task_state", required=False),
    Value("cycle_count", "uint32", "", "cycles run since start", "task.cycle_count"),
    Value("exceed_count", "uint32", "", "cycles that overran their period, plus the deadlines skipped after one",
          "task.exceed_count"),
    Value("last_exec_us", "float32", "us", "work time of the last cycle", "task.last_exec_us"),
    Value("cycle_time_us", "float32", "us", "configured cycle time", "task.cycle_time_us", required=False),
    Value("period_jitter_us", "float32", "us", "|actual - nominal period| of the last cycle",
          "task.period_jitter_us", required=False),
    Value("cycle_exceeded", "uint16", "", "1 if the last cycle overran its period", "task.cycle_exceeded",
          required=False),
    *(Value(f"correction_q{i}", "float32", "deg", f"joint {i} correction to add to q_r, after limits",
            f"signals.correction[{i - 1}]") for i in _JOINTS),
    *(Value(f"wrench_{c}", "float32", "N" if c[0] == "f" else "Nm",
            "filtered, gravity-compensated wrench, base axes (moments about the sensor origin)",
            f"signals.wrench_base[{k}]") for k, c in enumerate(_WRENCH)),
    *(Value(f"deflection_{c}", "float32", "mm" if k < 3 else "deg", "predicted TCP deflection, base axes",
            f"signals.deflection[{k}]") for k, c in enumerate(_DEFLECTION)),
    *(Value(f"dq_q{i}", "float32", "deg", f"joint {i} correction before limits (what the model asks for)",
            f"signals.dq_deg[{i - 1}]", required=False) for i in _JOINTS),
    Value("tare_count", "uint16", "", "tares done since start (wraps at 65535)", "signals.tare_count",
          required=False),
    Value("sensor_samples", "uint32", "", "good sensor samples since start", "signals.sensor_samples",
          required=False),
    Value("sample_age_ms", "float32", "ms", "age of the newest good sensor sample", "signals.sample_age_ms",
          required=False),
    Value("payload_active", "uint16", "", "the payload set in use (gravity.payloads index; 0 the gravity "
          "section's bodies); during a switch the old one until its ramp ends", "signals.payload_active",
          required=False),
    Value("reload_count", "uint16", "", "accepted reloads of the config since start (SIGHUP, stiffcomp reload; "
          "wraps at 65535)", "signals.reload_count", required=False),
)

FROM_PLC: tuple[Value, ...] = (
    Value("command_word", "uint16", "", "Command bits: 0 enable, 1 tare (rising edge), 2 reset faults (rising edge); "
          "any other bit is the fault command_invalid"),
    Value("plc_heartbeat", "uint16", "", "the PLC changes it at least every faults.plc_heartbeat_timeout_ms"),
    *(Value(f"q{i}", "float32", "deg", f"actual position of joint {i}") for i in _JOINTS),
    Value("payload_index", "uint16", "", "the payload set to use (gravity.payloads index; 0 the gravity "
          "section's bodies; a map without it reads 0); an index with no set is the fault payload_invalid",
          required=False),
    Value("plan_time_s", "float32", "s", "the PLC program's time in the process plan of the feedforward "
          "(dynamics.feedforward, source file); negative: no program running", required=False),
    Value("plan_engagement", "float32", "", "the engagement (0..1) the PLC program plans "
          "dynamics.feedforward.lookahead_ms ahead (source plc)", required=False),
    *(Value(f"acc_{a}", "float32", "m/s2", f"the flange accelerometer along its {a} axis as it measures (the specific "
            "force: gravity and its bias in it), scaled by the PLC from the box's process data", required=False)
      for a in "xyz"),
    Value("acc_samples", "uint16", "", "the accelerometer's new, valid samples the PLC has seen (wraps at 65535); "
          "unchanged past accelerometer.timeout_ms: frozen or missing", required=False),
)

ACCELEROMETER = ("acc_x", "acc_y", "acc_z", "acc_samples")    # bound all together or not at all

VALUES: dict[str, dict[str, Value]] = {"to_plc": {v.name: v for v in TO_PLC},
                                       "from_plc": {v.name: v for v in FROM_PLC}}
REQUIRED: dict[str, list[str]] = {d: [v.name for v in vs.values() if v.required] for d, vs in VALUES.items()}

# The records, one field per contract name (float for every value: integers are carried exactly).
ToPlc = NamedTuple("ToPlc", [(v.name, float) for v in TO_PLC])
ToPlc.__doc__ = "One cycle's values for the PLC, one field per `TO_PLC` name."
FromPlc = NamedTuple("FromPlc", [(v.name, float) for v in FROM_PLC])
FromPlc.__doc__ = "The PLC's values as the cycle reads them, one field per `FROM_PLC` name."


class TaskValues(NamedTuple):
    """The task's counters of one cycle (the ``task`` of a source path)."""

    heartbeat: int
    task_state: int
    cycle_count: int
    exceed_count: int
    last_exec_us: float
    cycle_time_us: float
    period_jitter_us: float
    cycle_exceeded: int


_SOURCE = re.compile(r"^(task|signals)\.([a-z_][a-z0-9_]*)(?:\[(\d+)\])?$")
_ROOTS = ("task", "signals")


class Source(NamedTuple):
    """A parsed ``source`` path: the root (``task`` or ``signals``), the attribute and an optional index."""

    root: str
    name: str
    index: int | None

    @classmethod
    def parse(cls, text: str) -> Source:
        m = _SOURCE.match(text)
        if m is None:
            raise ContractError(f"contract source {text!r} must be 'task.NAME' or 'signals.NAME[INDEX]'")
        root, name, index = m.groups()
        return cls(root, name, None if index is None else int(index))

    def read(self, task: TaskValues, signals: Any) -> Any:
        """The value on one cycle's records (the slow way: one source at a time)."""
        v = getattr(task if self.root == "task" else signals, self.name)
        return v if self.index is None else v[self.index]


def _tuple_getter(make: Callable[..., Callable[[Any], Any]], keys: list) -> Callable[[Any], tuple]:
    """``make(*keys)`` (operator.attrgetter or itemgetter), returning a tuple for any number of keys."""
    if len(keys) > 1:
        return make(*keys)
    if keys:
        one = make(keys[0])
        return lambda obj: (one(obj),)
    return lambda obj: ()


def _compile(sources: tuple[Source, ...], task: TaskValues, signals: Any) -> Callable[[TaskValues, Any], tuple]:
    """One getter of all ``sources``, in their order, for records shaped as ``task`` and ``signals``.

    One attrgetter per root reads every attribute a source names; the lists a source indexes are
    appended whole (their lengths taken from these records); one itemgetter then picks the values in
    the order of ``sources``. Lists whose length changes later (their sum, checked every cycle for the
    price of one ``len``) raise ContractError.
    """
    names = {r: list(dict.fromkeys(s.name for s in sources if s.root == r)) for r in _ROOTS}
    read_task, read_signals = (_tuple_getter(attrgetter, names[r]) for r in _ROOTS)
    whole = [Source(r, n, None) for r in _ROOTS for n in names[r]]          # what the attrgetters return
    lists = list(dict.fromkeys(Source(s.root, s.name, None) for s in sources if s.index is not None))
    the_lists = _tuple_getter(itemgetter, [whole.index(s) for s in lists])
    sizes = [len(s.read(task, signals)) for s in lists]
    flat = whole + [s._replace(index=i) for s, n in zip(lists, sizes) for i in range(n)]
    order = _tuple_getter(itemgetter, [flat.index(s) for s in sources])
    size = len(flat)

    def values(task: TaskValues, signals: Any) -> tuple:
        got = read_task(task) + read_signals(signals)
        out = list(got)
        for seq in the_lists(got):
            out += seq
        if len(out) != size:
            raise ContractError(f"the lists {', '.join(f'{s.root}.{s.name}' for s in lists)} hold "
                                f"{[len(seq) for seq in the_lists(got)]} values, at start-up {sizes}")
        return order(out)

    return values


def _unchecked(task: TaskValues, signals: Any) -> tuple:
    raise ContractError("Producer.check(task, signals) must run before the first record is built")


class Producer:
    """Builds the `ToPlc` record of a cycle from its ``task`` and ``signals`` by the contract's sources.

    Each source path is parsed once into a `Source` (a root, a name and an index, checked against a
    strict pattern; no ``eval``). `check` reads every source on the first records, so a source that
    names a missing quantity fails at start-up, not in the cycle, and compiles the cycle's getter from
    operator.attrgetter/itemgetter for those records.
    """

    def __init__(self) -> None:
        self._sources = tuple(Source.parse(v.source) for v in TO_PLC)
        self._values: Callable[[TaskValues, Any], tuple] = _unchecked
        self._make = ToPlc._make

    def check(self, task: TaskValues, signals: Any) -> None:
        for v, s in zip(TO_PLC, self._sources):
            try:
                float(s.read(task, signals))
            except (AttributeError, IndexError, TypeError, ValueError) as e:
                raise ContractError(f"contract value {v.name!r}: source {v.source!r} does not resolve: {e}") from e
        self._values = _compile(self._sources, task, signals)

    def __call__(self, task: TaskValues, signals: Any) -> ToPlc:
        return self._make(self._values(task, signals))

    def indices(self, slots: dict[str, int]) -> list[int]:
        """Where each `TO_PLC` value lies (in `TO_PLC` order) in a cycle's values kept as one vector, ``slots``
        naming each place as a source path (``task.heartbeat``, ``signals.correction[0]``): the compiled
        service's record. ContractError names a value whose source has no place."""
        out = []
        for v, s in zip(TO_PLC, self._sources):
            key = f"{s.root}.{s.name}" + ("" if s.index is None else f"[{s.index}]")
            if key not in slots:
                raise ContractError(f"contract value {v.name!r}: source {v.source!r} has no place in the cycle's "
                                    "values")
            out.append(slots[key])
        return out


def to_plc(**values: float) -> ToPlc:
    """A `ToPlc` record: zero but for ``values`` (tests, tools, a service before its first cycle)."""
    return ToPlc(**{**dict.fromkeys(ToPlc._fields, 0.0), **values})


def stopped(record: ToPlc) -> ToPlc:
    """The record a stopped service leaves: zero correction, status STOPPED, task state STOP."""
    zero = {f"correction_q{i}": 0.0 for i in _JOINTS}
    return record._replace(status_word=int(Status.STOPPED), task_state=int(TaskState.STOP), **zero)
