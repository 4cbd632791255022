"""A virtual PLC: a real Modbus TCP client of the service, on its own cycle, driving a robot.

Each cycle (1-4 ms, on absolute deadlines) it

1. reads the service's ``to_plc`` block (FC4): corrections, status, heartbeat;
2. runs `PlcLogic.step(t, values)`: the joint references of its program plus the applied correction;
3. writes its ``from_plc`` block (FC16): command word, its heartbeat, the actual joints.

The robot's servos hold the commanded joints, so the actual joint positions it writes are
q_cmd = q_ref + δq_applied (what the encoders read).

Safe state (docs/hil.md). The PLC applies the service's correction only while the link is fresh:
a read succeeded and the service heartbeat changed within ``service_timeout_s``. Otherwise the target
is zero. The applied correction moves towards its target at most ``max_rate_deg_s`` per joint, so
a lost link brings the robot back to its uncorrected path without a jump. After a link loss, once
the service answers again, the PLC raises the reset bit (the faults the loss caused in the service,
e.g. plc_heartbeat, are cleared; a fault whose cause persists trips again) and holds it until it reads
the fault word clear or ``recovery.hold_s`` has passed (`plc_interface.recovery`): a one-cycle pulse could fall between two cycles
of a service that a loaded host stalls for longer than a PLC cycle. The first contact
counts as such a recovery: a PLC starting up resets the service's faults once as it enables.

Fault injection (`PlcFaults`): the heartbeat freezes at a time; the Modbus connection drops at a
time and comes back after a while.
"""

from __future__ import annotations

import logging
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

from plc_interface.contract import Command
from plc_interface.deadlines import Deadlines
from plc_interface.recovery import RecoveryReset
from plc_interface.register_map import RegisterMap

log = logging.getLogger("stiffcomp.virtual_plc")


@dataclass
class PlcFaults:
    """Faults to inject (times in s of the PLC's program time; None = never)."""

    heartbeat_stop_at: float | None = None
    drop_at: float | None = None
    drop_for_s: float = 0.0


class PlcLogic:
    """The PLC program: a pure function of time and what was read (no clock, no I/O).

    Parameters
    ----------
    rmap : RegisterMap
    reference : callable t -> six joint references (deg)
    compensate : bool
        Set the enable bit and apply the corrections (False: the uncompensated run).
    service_timeout_s : float
    max_rate_deg_s : float
    faults : PlcFaults
    delay_s : float
        Extra delay (s): the PLC applies each correction it read this much later (a slower fieldbus, a
        PLC task that runs late; the HIL's ``plc.extra_delay_ms``).
    plan : callable t -> (program time (s), engagement planned ahead), optional
        What the program writes to ``plan_time_s`` and ``plan_engagement`` where the map has them (the
        feedforward's plan, `service.dynamics`); without it: -1 (no program) and 0.
    """

    def __init__(self, rmap: RegisterMap, reference: Callable[[float], list[float]], compensate: bool = True,
                 service_timeout_s: float = 0.1, max_rate_deg_s: float = 2.0, faults: PlcFaults | None = None,
                 delay_s: float = 0.0, plan: Callable[[float], tuple[float, float]] | None = None):
        self.out_names = rmap.codecs["to_plc"].names
        self.in_names = rmap.codecs["from_plc"].names
        self._corr = [self.out_names.index(f"correction_q{i}") for i in range(1, 7)]
        self._hb = self.out_names.index("heartbeat")
        self.reference = reference
        self.compensate = compensate
        self.timeout = float(service_timeout_s)
        self.rate = float(max_rate_deg_s)
        self.faults = faults or PlcFaults()
        self.heartbeat = 0
        self.service_hb: float | None = None
        self.hb_change_t: float | None = None
        self.was_lost = True            # the first contact counts as a recovery: reset, then enable
        self.reset_pulse = False
        self.recovery = RecoveryReset()
        self._fw = self.out_names.index("fault_word")
        self.applied = [0.0] * 6
        self.t_prev: float | None = None
        self.link_ok = False
        self.payload_index = 0          # the payload set the program selects (gravity.payloads)
        self.delay = float(delay_s)
        self.plan = plan
        self._late: deque[tuple[float, list[float]]] = deque()      # (t, target) waiting for their time

    def step(self, t: float, to_plc: list[float] | None) -> tuple[list[float], list[float]]:
        """One cycle at ``t`` (s): the from_plc values (codec order) and q_cmd (deg)."""
        dt = 0.0 if self.t_prev is None else t - self.t_prev
        self.t_prev = t
        if to_plc is not None and to_plc[self._hb] != self.service_hb:
            self.service_hb = to_plc[self._hb]
            self.hb_change_t = t
        fresh = (to_plc is not None and self.hb_change_t is not None and t - self.hb_change_t <= self.timeout)
        if fresh and self.was_lost:
            self.recovery.recovered(t)
        self.reset_pulse = fresh and self.recovery.bit(t, int(to_plc[self._fw]))
        if not fresh and self.hb_change_t is not None:
            self.was_lost = True
        elif fresh:
            self.was_lost = False
        self.link_ok = fresh
        target = [to_plc[k] for k in self._corr] if (fresh and self.compensate) else [0.0] * 6
        if self.delay > 0:              # the newest target read at or before t - delay
            self._late.append((t, target))
            while len(self._late) > 1 and self._late[1][0] <= t - self.delay + 1e-9:
                self._late.popleft()
            t0, due = self._late[0]
            target = due if t0 <= t - self.delay + 1e-9 else [0.0] * 6
        step = self.rate * dt
        self.applied = [a + min(max(x - a, -step), step) for a, x in zip(self.applied, target)]
        q_ref = self.reference(t)
        q_cmd = [r + a for r, a in zip(q_ref, self.applied)]
        if self.faults.heartbeat_stop_at is None or t < self.faults.heartbeat_stop_at:
            self.heartbeat = (self.heartbeat + 1) & 0xFFFF
        command = int((Command.ENABLE if self.compensate else 0) | (Command.RESET if self.reset_pulse else 0))
        program_t, engagement = self.plan(t) if self.plan is not None else (-1.0, 0.0)
        values = {"command_word": command, "plc_heartbeat": self.heartbeat, "payload_index": self.payload_index,
                  "plan_time_s": program_t, "plan_engagement": engagement,
                  **{f"q{i + 1}": v for i, v in enumerate(q_cmd)}}
        return [values[n] for n in self.in_names], q_cmd


class CycleLog:
    """Per-cycle record of a PLC run, preallocated (t, read time, link, q_ref, q_cmd, applied, to_plc)."""

    def __init__(self, n: int, n_out: int):
        self.t = np.full(n, np.nan)
        self.t_read = np.full(n, np.nan)          # monotonic time the read completed
        self.link = np.zeros(n, dtype=bool)
        self.q_ref = np.zeros((n, 6))
        self.q_cmd = np.zeros((n, 6))
        self.applied = np.zeros((n, 6))
        self.to_plc = np.full((n, n_out), np.nan)
        self.k = 0

    def arrays(self) -> dict[str, np.ndarray]:
        k = self.k
        return {"t": self.t[:k], "t_read": self.t_read[:k], "link": self.link[:k], "q_ref": self.q_ref[:k],
                "q_cmd": self.q_cmd[:k], "applied": self.applied[:k], "to_plc": self.to_plc[:k]}


class VirtualPlc:
    """The PLC's I/O loop around `PlcLogic`, as a Modbus TCP client of the service.

    Parameters
    ----------
    logic : PlcLogic
    rmap : RegisterMap
    host, port : the service's Modbus server
    period_s : the PLC cycle (1-4 ms)
    timeout_s : per Modbus request
    reconnect_s : wait between connection attempts
    """

    def __init__(self, logic: PlcLogic, rmap: RegisterMap, host: str, port: int, period_s: float = 0.002,
                 timeout_s: float = 0.1, reconnect_s: float = 0.05):
        self.logic = logic
        self.host, self.port = host, port
        self.period = float(period_s)
        self.reconnect_s = reconnect_s
        self.client = ModbusTcpClient(host, port=port, timeout=timeout_s, retries=0)
        out, inp = rmap.blocks["to_plc"], rmap.blocks["from_plc"]
        self.out_codec, self.in_codec = rmap.codecs["to_plc"], rmap.codecs["from_plc"]
        self.read_start, self.write_start = out.start, inp.start
        self.read_fc4 = out.table == "input_registers"
        self.connected = False
        self.next_attempt = -np.inf
        self.written: set[int] = set()            # every address this PLC wrote
        self.overruns = 0
        self.errors = 0
        self.log: CycleLog | None = None

    def connect(self, deadline: float, clock: Callable[[], float] = time.monotonic) -> bool:
        """Try to connect until ``deadline`` (clock time); True when connected."""
        while clock() < deadline:
            if self.client.connect():
                self.connected = True
                return True
            time.sleep(0.05)
        return False

    def close(self) -> None:
        self.client.close()
        self.connected = False

    def _read(self) -> list[float] | None:
        n = self.out_codec.words
        fn = self.client.read_input_registers if self.read_fc4 else self.client.read_holding_registers
        r = fn(self.read_start, count=n)
        if r.isError():
            raise ModbusException(f"read refused: {r}")
        return self.out_codec.decode(r.registers)

    def _write(self, values: list[float]) -> None:
        words = self.in_codec.encode(values)
        r = self.client.write_registers(self.write_start, words)
        if r.isError():
            raise ModbusException(f"write refused: {r}")
        self.written.update(range(self.write_start, self.write_start + len(words)))

    def cycle(self, t: float, now: float) -> None:
        """Read, run the logic, write: one PLC cycle at program time ``t``."""
        f = self.logic.faults
        dropped = f.drop_at is not None and f.drop_at <= t < f.drop_at + f.drop_for_s
        if dropped and self.connected:
            self.close()
        if not dropped and not self.connected and now >= self.next_attempt:
            self.next_attempt = now + self.reconnect_s
            self.connected = bool(self.client.connect())
        values = None
        if self.connected:
            try:
                values = self._read()
            except (ModbusException, OSError):
                self.errors += 1
                self.close()
        t_read = time.monotonic()
        out, q_cmd = self.logic.step(t, values)
        if self.connected:
            try:
                self._write(out)
            except (ModbusException, OSError):
                self.errors += 1
                self.close()
        lg = self.log
        if lg is not None and lg.k < len(lg.t):
            k = lg.k
            lg.t[k], lg.t_read[k], lg.link[k] = t, t_read, self.logic.link_ok
            lg.q_ref[k] = self.logic.reference(t)
            lg.q_cmd[k] = q_cmd
            lg.applied[k] = self.logic.applied
            if values is not None:
                lg.to_plc[k] = values
            lg.k += 1

    def run(self, t_start: float, t_end: float, t0: float, clock: Callable[[], float] = time.monotonic) -> CycleLog:
        """Run cycles on absolute deadlines (`Deadlines`, the project's one catch-up rule) from program time
        ``t_start`` to ``t_end``; program time t = clock() - t0. Returns the cycle log.

        Each cycle runs, and is logged, at the program time it starts, not at its deadline. A real PLC's task
        starts on its deadline, so the two are one; this process is an ordinary one on a shared host, and after
        an overrun the catch-up rule starts the next cycle at once on a deadline up to a period past. Stamped
        with that deadline, the cycle's joints carried a correction read up to a period (4 ms) later than the
        log said, and the run measured the end-to-end delay that much short: 4.0 ms for 8 on a loaded host
        (issue 45). ``t_read`` still says when its read completed."""
        n = int((t_end - t_start) / self.period) + 16
        self.log = CycleLog(n, len(self.out_codec.names))
        deadlines = Deadlines(self.period, start=t0 + t_start, clock=clock)
        while deadlines.due - t0 <= t_end:
            deadlines.sleep_until()
            now = clock()
            self.cycle(now - t0, now)
            deadlines.advance(clock())
            self.overruns = deadlines.exceeded
        return self.log
