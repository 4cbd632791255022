"""One cycle of the compensation, as a pure function of time and inputs (no clock, no I/O).

    sample -> spike rejection -> low-pass -> gravity compensation -> base axes -> deflection (model)
           -> δq (Jacobian pseudo-inverse) -> limits -> outputs

`Compensator` is the signal path alone; `service.supervision.Supervisor` decides beside it whether the
correction may be applied; `Cycle` runs the two in order and returns the cycle's `Signals`, the
record the contract's to_plc values are taken from (``signals.NAME``). A replay or a test drives
`Cycle.step(t, ...)` exactly as the live loop does.
"""

from __future__ import annotations

import logging
import math
from typing import NamedTuple

import numpy as np
from pydantic import Field

from plc_interface.contract import SENSOR_FAULTS, Fault, Status
from stiffness.model import StiffnessModel
from stiffness.units import DEG_TO_RAD, M_TO_MM, RAD_TO_DEG
from stiffness.yamlio import Strict

from .ati import Reading
from .compensation import FastPredictor, ModelConfig
from .dynamics import Dynamics
from .errors import SensorError
from .faults import FaultMonitor
from .filters import FilterConfig, SosLowPass, SpikeRejector
from .gravity import GravityCompensator, GravityConfig
from .limits import CorrectionLimiter, LimitsConfig
from .payloads import PayloadSelector
from .supervision import Supervisor

log = logging.getLogger("stiffcomp.service")

_OUT_SCALE = np.array([M_TO_MM, M_TO_MM, M_TO_MM, RAD_TO_DEG, RAD_TO_DEG, RAD_TO_DEG])
# the status bits as plain ints: IntFlag arithmetic costs microseconds in a 1 ms cycle
_RUNNING, _ACTIVE, _FAULTED, _RAMPING, _SENSOR_OK, _PLC_SEEN, _TARE_REFUSED = (int(b) for b in (
    Status.RUNNING, Status.ACTIVE, Status.FAULTED, Status.RAMPING, Status.SENSOR_OK, Status.PLC_SEEN,
    Status.TARE_REFUSED))
_SENSOR_FAULTS = int(SENSOR_FAULTS)


class Signals(NamedTuple):
    """What one cycle computed (the ``signals`` of the contract's sources)."""

    status_word: int
    fault_word: int
    correction: list[float]         # δq after limits, deg
    dq_deg: list[float]             # δq before limits, deg
    wrench_base: list[float]        # filtered, compensated wrench, base axes (N, Nm about the sensor origin)
    wrench_sensor: list[float]      # the same in sensor axes
    deflection: list[float]         # predicted TCP deflection, mm and deg, base axes
    tare_count: int
    sensor_samples: int             # good samples since start
    sample_age_ms: float            # age of the newest good sample (ms; since start before the first)
    payload_active: int             # the payload set in use (service.payloads)
    reload_count: int               # accepted reloads of the config (service.reload)


class TareConfig(Strict):
    """``tare``: a tare is refused while the compensated force exceeds ``max_force_N`` (a tare under a
    cutting load would zero the load)."""

    max_force_N: float = Field(200.0, gt=0)


class Compensator:
    """The signal path: from a sample and the joint positions to the limited joint correction.

    Parameters
    ----------
    predictor, filter, spikes, gravity, limiter : the stages
    faults : FaultMonitor
        Where a correction that is not finite trips ``value_invalid``.
    tare_max_force_N : float
        A tare is refused while the compensated force |F| is above this (a tare under load would zero
        the load); ``tare_refused`` says so until a tare is done or the faults are reset.
    payloads : PayloadSelector, optional
        The payload table the PLC selects from (`service.payloads`; its `PayloadSelector.reload` takes a
        new ``gravity`` section at run time); by default only the payload ``gravity`` holds, as index 0.
    dynamics : Dynamics, optional
        The dynamic compensation (`service.dynamics`), whose terms ``predictor`` already runs; the cycle feeds
        its parts the PLC's values they read (the feedforward's plan) before the prediction.
    """

    def __init__(self, predictor: FastPredictor, filter: SosLowPass, spikes: SpikeRejector,
                 gravity: GravityCompensator, limiter: CorrectionLimiter, faults: FaultMonitor,
                 tare_max_force_N: float = math.inf, payloads: PayloadSelector | None = None,
                 dynamics: Dynamics | None = None):
        self.predictor = predictor
        self.dynamics = dynamics
        self.feeds = dynamics is not None and bool(dynamics.plc_values())
        predictor.carry(gravity.mass, gravity.cog, gravity.g)      # the payload in the static torque
        self.payloads = payloads or PayloadSelector.only(gravity, predictor, faults)
        self.filter = filter
        self.spikes = spikes
        self.gravity = gravity
        self.limiter = limiter
        self.faults = faults
        self.t_prev: float | None = None
        self.have_sample = False
        self.wrench_sensor = [0.0] * 6
        self.filtered = [0.0] * 6               # the last sample, filtered (sensor axes)
        self.wrench_base = [0.0] * 6
        self.deflection = [0.0] * 6
        self.dq_deg = [0.0] * 6
        self.correction = [0.0] * 6
        self.q_rad = np.zeros(6)
        self.tares = 0
        self.samples = 0
        self.sample_t: float | None = None
        self.t_first: float | None = None
        self._tare_pending = False            # a tare edge waits for the next sample
        self.tare_max = float(tare_max_force_N)
        self.tare_refused = False
        self.kernel = None                      # the compiled signal path (`compile`), None: the Python path

    def compile(self) -> None:
        """Run the signal path compiled from the next cycle on (`service.kernel`): numba compiles, or loads
        from its disk cache, here, before any cycle. Raises `service.kernel.NotCompilable` (the reason in
        its message) when the model has no compiled form; the compensator then stays on the Python path."""
        from .kernel.compensator import CompiledSignal

        pred = self.predictor
        pred.compile()
        k = CompiledSignal()
        k.bind(self)
        k.condition([0.0] * 6)                  # compile or load now, then restore the state
        pk = pred.kernel
        self._signal_path(k, pk, False, 0.0, True)
        k.bind(self)
        pk.ws[:] = self.wrench_sensor
        pred.reset_history()
        self.kernel = k

    @classmethod
    def from_config(cls, model_section: ModelConfig, filter_section: FilterConfig, gravity: GravityConfig,
                    limits: LimitsConfig, tare: TareConfig, period_s: float, model: StiffnessModel,
                    faults: FaultMonitor, dynamics: Dynamics | None = None) -> Compensator:
        """Each part from its own section: ``model``, ``filter``, ``gravity``, ``limits``, ``tare`` (and the
        dynamic compensation built from ``dynamics``)."""
        predictor = FastPredictor.from_config(model_section, model, dynamics)
        compensator = GravityCompensator.from_config(gravity)
        return cls(predictor, SosLowPass.from_config(filter_section, period_s),
                   SpikeRejector.from_config(filter_section.spike), compensator,
                   CorrectionLimiter.from_config(limits, period_s), faults, tare.max_force_N,
                   PayloadSelector.from_config(gravity, compensator, predictor, faults), dynamics)

    def _tare(self, filtered: list[float]) -> None:
        """The tare edge's work on a sample: refused under load, else the current wrench becomes zero."""
        pred = self.predictor
        fx, fy, fz = self.gravity.compensate(filtered, pred.R_s)[:3]
        load = math.sqrt(fx * fx + fy * fy + fz * fz)
        if load > self.tare_max:
            self.tare_refused = True
            log.warning("tare refused: the compensated force is %.0f N, above tare.max_force_N = %g N (a tare "
                        "under load would zero the load); unload the tool and tare again", load, self.tare_max)
            return
        self.tare_refused = False
        self.gravity.tare(filtered, pred.R_s)
        self.tares += 1
        pred.reset_history()
        log.info("tare: bias is now %s", np.array2string(self.gravity.bias, precision=2))

    def cycle(self, t: float, reading: Reading | None, q_deg: list[float] | None, tare: bool,
              hold: bool, reset: bool = False, payload_index: int = 0, inputs=None) -> list[float]:
        """One cycle at ``t`` (s); returns the limited joint correction (deg, six floats).

        ``q_deg``: new joint positions (None: unchanged); ``tare``: a tare edge (applied to the next
        sample); ``hold``: the correction must ramp to zero (not enabled, or stopping); ``reset``: the
        faults were reset this cycle; ``payload_index``: the PLC's selection (`service.payloads`);
        ``inputs``: the PLC's `FromPlc` record, for the dynamic compensation's parts that read a value of it.

        The model's history (hysteresis) restarts at its defined state at the first sample (what came
        before was no measurement), when a tare is applied (the wrench jumps by the bias, not by a
        load) and on a fault reset (the wrench before it is not trusted).
        """
        dt = 0.0 if self.t_prev is None else t - self.t_prev
        self.t_prev = t
        if self.t_first is None:
            self.t_first = t
        pred = self.predictor
        if self.feeds and inputs is not None:
            self.dynamics.feed(t, inputs, pred.p_tcp)
        k = self.kernel
        compiled = k is not None and pred.kernel is not None
        if k is not None and not compiled and k.bound:     # a model reload's ramp: the Python path takes over
            k.unbind(self)
        if q_deg is not None:                   # the steps both paths take first
            self.q_rad = np.array(q_deg) * DEG_TO_RAD
            pred.kinematics(self.q_rad)
        if tare:
            self._tare_pending = True
        if reset:
            pred.reset_history()
            self.tare_refused = False
        moved = self.payloads.update(dt, payload_index)
        if compiled:
            return self._cycle_compiled(k, pred, t, dt, reading, hold, moved)
        if reading is not None:
            self.samples += 1
            self.sample_t = t
            x = self.spikes.update(reading.wrench)
            if not self.have_sample:
                self.filter.state = self.filter.steady_state(x)
                self.have_sample = True
                pred.reset_history()
            self.filtered = filtered = self.filter.update(x)
            if self._tare_pending:
                self._tare_pending = False
                self._tare(filtered)
            self.wrench_sensor = self.gravity.compensate(filtered, pred.R_s)
        elif moved and self.have_sample:        # a switch's ramp goes on between samples too: no catch-up step
            self.wrench_sensor = self.gravity.compensate(self.filtered, pred.R_s)
        self.wrench_base = pred.wrench_base(self.wrench_sensor)
        dX = pred.deflection(self.wrench_base, dt)
        dq = pred.correction(self.q_rad, dX)
        self.deflection = (dX * _OUT_SCALE).tolist()
        self.dq_deg = dq_deg = (dq * RAD_TO_DEG).tolist()
        if not math.isfinite(sum(dq_deg)):          # NaN and inf propagate through the sum
            self.faults.trip(Fault.VALUE_INVALID, "the predicted correction is not finite")
            dq_deg = [0.0] * 6
        safe = self.faults.word != 0 or hold or not self.have_sample
        self.correction = self.limiter.update(dt, dq_deg, safe)
        return self.correction


    def _cycle_compiled(self, k, pred, t: float, dt: float, reading: Reading | None, hold: bool,
                        moved: bool) -> list[float]:
        """`cycle` on the compiled path after the steps both paths take first (``moved``: the payload's
        switch moved): the arithmetic in two compiled calls (three when the joints moved); the state of the
        stages lives in ``k`` (`service.kernel.compensator`)."""
        b, sp, f, lim = k.bound, self.spikes, self.filter, self.limiter
        if (not b or sp is not b[0] or sp.max_step is not b[1] or sp.max_held is not b[2] or f is not b[3]
                or lim is not b[4] or lim.max is not b[5] or lim.rate is not b[6] or lim.ramp_s is not b[7]):
            k.rebind(self)                      # a reload replaced a stage or its parameters (k.key)
        gravity_on = False
        if reading is not None:
            self.samples += 1
            self.sample_t = t
            if not self.have_sample:            # the first sample: the filter starts in its steady state
                k.unbind(self)
                x = self.spikes.update(reading.wrench)
                self.filter.state = self.filter.steady_state(x)
                self.have_sample = True
                pred.reset_history()
                filtered = self.filter.update(x)
                k.bind(self)
                k.y[:] = filtered
            else:
                filtered = self.filter.y = k.condition(reading.wrench)
            self.filtered = filtered
            if self._tare_pending:
                self._tare_pending = False
                self._tare(filtered)
            gravity_on = True
        elif moved and self.have_sample:        # a switch's ramp goes on between samples too
            gravity_on = True
        safe = self.faults.word != 0 or hold or not self.have_sample
        finite = self._signal_path(k, pred.kernel, gravity_on, dt, safe)
        pk = pred.kernel
        self.wrench_sensor, self.wrench_base = pk.ws.tolist(), pk.wb.tolist()
        self.deflection = np.multiply(pk.dX, _OUT_SCALE, out=k.deflection).tolist()
        self.dq_deg = k.dq_deg.tolist()
        if not finite:
            self.faults.trip(Fault.VALUE_INVALID, "the predicted correction is not finite")
        self.correction = lim.out = k.out.tolist()
        lim.safe = bool(k.lim[14])
        return self.correction

    def _signal_path(self, k, pk, gravity_on: bool, dt: float, safe: bool) -> bool:
        if k.args[0] is not pk:                 # the arrays of this predictor, gathered once
            k.args = (pk, (pk.ws, pk.Rs, pk.ps, pk.Ad, pk.comp, pk.tau_s, pk.axj, pk.axl, pk.axp, pk.at_rest, pk.hj,
                           pk.hl, pk.hp, pk.hs, pk.hg, pk.fm, pk.fC, pk.wl, pk.wp, pk.wst, pk.tl, pk.tp, pk.tst),
                      (pk.Ttcp, pk.Jp, pk.w0, pk.local, pk.delta, pk.wb, pk.dX, pk.dq, k.dq_deg))
        _, before, after = k.args
        return pk.mod.signal_path(gravity_on, k.y, self.gravity.gp, *before, dt, *after, safe, k.lim, k.out,
                                  k.ramp_rate)


class Cycle:
    """Supervision, then the signal path: one whole cycle of the service.

    Parameters
    ----------
    supervisor : Supervisor
    compensator : Compensator
        Both share one `FaultMonitor`.
    """

    def __init__(self, supervisor: Supervisor, compensator: Compensator):
        self.supervisor = supervisor
        self.compensator = compensator
        self.faults = compensator.faults
        self.stopping = False           # the stop request: ramp to zero, then the task ends
        self.reloads = 0                # accepted reloads, counted by the reload's swap (service.reload)
        self.status_word = 0

    @classmethod
    def from_config(cls, cfg, model: StiffnessModel) -> Cycle:
        """The cycle as the service config composes it: each part is handed its own section."""
        faults = FaultMonitor()
        period = cfg.cycle.period_ms / 1000.0
        dynamics = Dynamics(cfg.dynamics, period, cfg.resolve)
        if dynamics.active:
            log.info("%s", dynamics.describe())
        return cls(Supervisor.from_config(cfg.faults, faults, model.robot.limits_deg, cfg.plc.enable_on_start),
                   Compensator.from_config(cfg.model, cfg.filter, cfg.gravity, cfg.limits, cfg.tare, period,
                                           model, faults, dynamics if dynamics.active else None))

    def step(self, t: float, reading: Reading | None, errors: list[SensorError], command: int,
             plc_heartbeat: int, q_deg: list[float], overrun: bool = False, payload_index: int = 0,
             inputs=None) -> list[float]:
        """Run one cycle at time ``t`` (s); returns the limited joint correction (deg, six floats). ``inputs``:
        the PLC's whole `FromPlc` record (the dynamic compensation's feedforward reads its plan there)."""
        s = self.supervisor.update(t, command, plc_heartbeat, q_deg, overrun, errors)
        comp = self.compensator
        out = comp.cycle(t, reading, s.q_deg, s.tare, not s.enabled or self.stopping, s.reset, payload_index,
                         inputs)
        word = self.faults.word
        self.status_word = (_RUNNING | (0 if comp.limiter.safe else _ACTIVE) | (_FAULTED if word else 0)
                            | (_RAMPING if comp.limiter.ramping else 0)
                            | (_SENSOR_OK if comp.have_sample and not word & _SENSOR_FAULTS else 0)
                            | (_PLC_SEEN if self.supervisor.plc_seen else 0)
                            | (_TARE_REFUSED if comp.tare_refused else 0))
        return out

    def signals(self) -> Signals:
        """The record of the last cycle."""
        c = self.compensator
        since = c.sample_t if c.sample_t is not None else c.t_first
        age_ms = 0.0 if since is None else (c.t_prev - since) * 1000.0
        return Signals(self.status_word, self.faults.word, c.correction, c.dq_deg, c.wrench_base,
                       c.wrench_sensor, c.deflection, c.tares, c.samples, age_ms, c.payloads.active.index,
                       self.reloads & 0xFFFF)

    # what a test or a log reads of the last cycle (the signal path's values)
    correction = property(lambda self: self.compensator.correction)
    dq_deg = property(lambda self: self.compensator.dq_deg)
    wrench_base = property(lambda self: self.compensator.wrench_base)
    wrench_sensor = property(lambda self: self.compensator.wrench_sensor)
    deflection = property(lambda self: self.compensator.deflection)
    tares = property(lambda self: self.compensator.tares)
