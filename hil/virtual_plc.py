"""The HIL's virtual PLC: the TwinCAT program the cell loads (`hil.plc_program`), run by the structured-text
runtime (`st_runtime`) on the PLC's cycle, its requests going to the service over the cell's network
(`hil.cell_network`), driving the robot.

Each cycle (``plc.period_ms``, on absolute deadlines in real time) it

1. sets the program's clock to the cycle's program time and writes MAIN's inputs: the path's joint references
   (``aReferenceDeg``), the robot's joints (``aJointsDeg``: the servos hold the last command), ``bEnable``,
   and the feedforward's plan where MAIN has it;
2. runs MAIN once: FB_StiffCompModbus's requests, its link and validity checks, the rate limit;
3. drives the robot with ``aCommandDeg`` and logs the cycle.

Everything a PLC decides (when the link is alive, the reset after a loss, the rate limit, what a fault does)
is the program's; this module only moves its inputs and outputs, as a cell's I/O mapping does. The safe state
is therefore the library's (docs/plc.md, "The block's state table").
"""

from __future__ import annotations

import struct
import time
from collections.abc import Callable

import numpy as np

from io_base.deadlines import Deadlines
from plc_link.register_map import RegisterMap
from st_runtime import f32

from .cell_network import CellNetwork
from .device_log import PlcLog
from .plc_program import PlcProgram


class CycleLog:
    """Per-cycle record of a PLC run, preallocated (t, read time, link, q_ref, q_cmd, applied, to_plc)."""

    def __init__(self, n: int, n_out: int):
        self.t = np.full(n, np.nan)
        self.t_read = np.full(n, np.nan)          # monotonic time the cycle's requests were done
        self.link = np.zeros(n, dtype=bool)
        self.q_ref = np.zeros((n, 6))
        self.q_cmd = np.zeros((n, 6))
        self.applied = np.zeros((n, 6))
        self.to_plc = np.full((n, n_out), np.nan)
        self.rows = 0                   # the cycles logged so far



class VirtualPlc:
    """The program on its runtime, and its cell.

    Parameters
    ----------
    program : PlcProgram
    network : CellNetwork (`TcpNetwork` in real time, `ImageNetwork` in lock step)
    rmap : the service's register map (to log the service's record as the program read it)
    reference : callable t -> six joint references (deg)
    compensate : MAIN's ``bEnable`` (False: the uncompensated pass)
    period_s : the PLC's cycle (whole milliseconds: the runtime's clock counts ms)
    plan : callable t -> (program time (s), engagement planned ahead), for MAIN's plan inputs where it has them
    settings : the scenario's ``service_timeout_ms`` and ``max_rate_deg_s`` (`PlcProgram.start`)
    accelerometer : the box at the tool (`hil.accelerometer.VirtualAccelerometer`), for MAIN's box inputs where
        it has them (a map that binds the accelerometer); None: none
    """

    def __init__(self, program: PlcProgram, network: CellNetwork, rmap: RegisterMap,
                 reference: Callable[[float], list[float]], compensate: bool, period_s: float,
                 plan: Callable[[float], tuple[float, float]] | None = None, settings: dict | None = None,
                 accelerometer=None):
        self.cycle_ms = round(period_s * 1000.0)
        self.period = self.cycle_ms / 1000.0
        self.network = network
        self.runtime, self.main = program.start(network, self.cycle_ms, **(settings or {}))
        self.main.bEnable = bool(compensate)
        self.fb = self.main.fbStiffComp
        self.reference = reference
        self.plan = plan
        self.accelerometer = accelerometer if hasattr(self.main, "nAccX") else None
        self._tare_from: float | None = None
        self._alive_from: float | None = None
        self.out_codec = rmap.codecs["to_plc"]
        self._words = struct.Struct(f"<{self.out_codec.words}H")
        self.q_cmd: list[float] | None = None
        self.overruns = 0
        self.log: CycleLog | None = None

    def new_log(self, n: int) -> CycleLog:
        self.log = CycleLog(n, len(self.out_codec.names))
        return self.log

    def cycle(self, t: float, done: Callable[[], float] = time.monotonic) -> list[float]:
        """One PLC cycle at program time ``t`` (s): the robot's command (deg). ``done`` stamps the log's
        ``t_read``, when the cycle's requests were done (the monotonic clock; lock step: the program time)."""
        m = self.main
        self.runtime.now_ms = round(t * 1000.0)
        m.aReferenceDeg[:] = [f32(x) for x in self.reference(t)]
        m.aJointsDeg[:] = m.aReferenceDeg if self.q_cmd is None else self.q_cmd
        if self.plan is not None and hasattr(m, "fPlanTimeS"):
            program_t, engagement = self.plan(t)
            m.fPlanTimeS, m.fPlanEngagement = f32(program_t), f32(engagement)
        if self.accelerometer is not None:          # the box's process data, as EtherCAT brings them
            for name, value in self.accelerometer.sample(t, list(m.aJointsDeg)).items():
                setattr(m, name, value)
            m.bTare = self._tare_at(t)
        m.body()
        self.q_cmd = list(m.aCommandDeg)
        self._record(t, done())
        return self.q_cmd

    def _tare_at(self, t: float) -> bool:
        """With an accelerometer, MAIN's tare input: one rising edge while the arm stands at the start of the lead,
        0.1 s after the service is first alive (the correction's first ramp is over by then) and at least 0.2 s
        before the cut (program time 0), held 50 ms, as a cell tares its sensors at rest before a cut; the wrench
        is tared with it."""
        if self.fb.bAlive and self._alive_from is None:
            self._alive_from = t
        if self._tare_from is None and self._alive_from is not None and t - self._alive_from >= 0.1 and t < -0.2:
            self._tare_from = t
        return self._tare_from is not None and t - self._tare_from < 0.05

    def _record(self, t: float, t_read: float) -> None:
        lg = self.log
        if lg is None or lg.rows >= len(lg.t):
            return
        k = lg.rows
        lg.t[k], lg.t_read[k], lg.link[k] = t, t_read, self.fb.bAlive
        lg.q_ref[k] = self.main.aReferenceDeg
        lg.q_cmd[k] = self.q_cmd
        lg.applied[k] = lg.q_cmd[k] - lg.q_ref[k]
        if self.fb.bAlive:
            raw = self.fb.stToPlc.to_bytes()[:self._words.size]
            lg.to_plc[k] = self.out_codec.decode(list(self._words.unpack(raw)))
        lg.rows += 1

    def device_log(self, t0: float) -> PlcLog:
        """The cycles logged so far, with what the network saw (the addresses written, the failed requests, what
        was dialled) and the overruns; ``t0``: the clock time of program time 0."""
        lg, net = self.log, self.network
        k = lg.rows
        return PlcLog(t=lg.t[:k], q_ref=lg.q_ref[:k], q_cmd=lg.q_cmd[:k], applied=lg.applied[:k], period=self.period,
                      t0=t0, overruns=self.overruns, t_read=lg.t_read[:k], link=lg.link[:k], to_plc=lg.to_plc[:k],
                      written=np.array(sorted(net.written)), errors=net.errors, dialled=np.array(sorted(net.dialled)))

    def run(self, t_start: float, t_end: float, t0: float, clock: Callable[[], float] = time.monotonic) -> PlcLog:
        """Run cycles on absolute deadlines (`Deadlines`, the project's one catch-up rule) from program time
        ``t_start`` to ``t_end``; program time t = clock() - t0. Returns the PLC's log (`device_log`).

        Each cycle runs, and is logged, at the program time it starts, not at its deadline: after an overrun the
        catch-up rule starts the next cycle at once on a deadline up to a period past, and stamped with that
        deadline its joints would carry a correction read up to a period later than the log said."""
        self.new_log(int((t_end - t_start) / self.period) + 16)
        deadlines = Deadlines(self.period, start=t0 + t_start, clock=clock)
        while deadlines.due - t0 <= t_end:
            deadlines.sleep_until()
            now = clock()
            self.cycle(now - t0)
            deadlines.advance(clock())
            self.overruns = deadlines.exceeded
        return self.device_log(t0)
