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

import numpy as np
from pydantic import Field

from plc_link.contract import Fault, Status
from stiffness.files.yaml_schema import Strict
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.units import DEG_TO_RAD, M_TO_MM, RAD_TO_DEG

from .accelerometer import Accelerometer
from .ati import Reading
from .compensation import FastPredictor, ModelConfig
from .cycle_rules import safe_state, sample_age_ms, status_word
from .dynamics import Dynamics
from .errors import SensorError
from .faults import FaultMonitor
from .filters import FilterConfig, SosLowPass, SpikeRejector
from .gravity import GravityCompensator, GravityConfig
from .limits import CorrectionLimiter, LimitsConfig
from .payloads import PayloadSelector
from .signals import SCALAR_AT, SCALARS, SIGNAL_SIZE, VECTORS_SIZE, VECTORS_START, Signals, six
from .supervision import Supervisor

log = logging.getLogger("stiffcomp.service")

_OUT_SCALE = np.array([M_TO_MM, M_TO_MM, M_TO_MM, RAD_TO_DEG, RAD_TO_DEG, RAD_TO_DEG])
_MOVED, _FRESH, _GRAVITY, _SAFE = 1, 2, 4, 8      # the compiled cycle's flags (`service.kernel.template.cycle`)
# the scalars' places in `Cycle.vector`
_STATUS, _FAULT, _TARES, _SAMPLES, _AGE, _PAYLOAD, _RELOADS, _ACC = (SCALAR_AT[n] for n in SCALARS[:8])
_BOX, _BOX_SAMPLES = SCALAR_AT["box_x"], SCALAR_AT["box_samples"]


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
    accelerometer : Accelerometer, optional
        The flange accelerometer (`service.accelerometer`), read from the PLC's values after the signal path.
    """

    def __init__(self, predictor: FastPredictor, filter: SosLowPass, spikes: SpikeRejector,
                 gravity: GravityCompensator, limiter: CorrectionLimiter, faults: FaultMonitor,
                 tare_max_force_N: float = math.inf, payloads: PayloadSelector | None = None,
                 dynamics: Dynamics | None = None, accelerometer: Accelerometer | None = None):
        self.predictor = predictor
        self.dynamics = dynamics
        self.accelerometer = accelerometer if accelerometer is not None and accelerometer.enabled else None
        self.feeds = dynamics is not None and bool(dynamics.plc_values()) or self.accelerometer is not None
        predictor.carry(gravity.mass, gravity.cog, gravity.g_mps2)     # the payload in the static torque
        self.payloads = payloads or PayloadSelector.only(gravity, predictor, faults)
        self.filter = filter
        self.spikes = spikes
        self.gravity = gravity
        self.limiter = limiter
        self.faults = faults
        self.t_prev: float | None = None
        self.have_sample = False
        self.vector = np.zeros(VECTORS_SIZE)    # the cycle's outputs, in Signals' order (the properties below)
        self.filtered = [0.0] * 6               # the last sample, filtered (sensor axes)
        self.ramping = False                    # the limiter ramps the correction to zero
        self.q_rad = np.zeros(6)
        self.tares = 0
        self.samples = 0
        self.sample_t: float | None = None
        self.t_first: float | None = None
        self._tare_pending = False            # a tare edge waits for the next sample
        self.tare_max = float(tare_max_force_N)
        self.tare_refused = False
        self.kernel = None                      # the compiled signal path (`compile`), None: the Python path
        self._pk = None                         # the compiled predictor of the last compiled cycle

    correction = six("correction", "δq after limits, deg (the cycle's output)")
    dq_deg = six("dq_deg", "δq before limits, deg")
    wrench_base = six("wrench_base", "the filtered, compensated wrench in base axes (N, Nm about the sensor origin)")
    wrench_sensor = six("wrench_sensor", "the same in sensor axes")
    deflection = six("deflection", "the predicted TCP deflection, mm and deg, base axes")

    def attach(self, vector: np.ndarray) -> None:
        """Keep the outputs in ``vector`` (`VECTORS_SIZE` floats, a view of `Cycle.vector`) from now on."""
        vector[:] = self.vector
        self.vector = vector

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
        pk.cycle(k.S, np.zeros(VECTORS_SIZE), _FRESH | _SAFE, 0.0)
        k.bind(self)
        pk.ws[:] = self.wrench_sensor
        pred.reset_history()
        self.kernel = k

    @classmethod
    def from_config(cls, model_section: ModelConfig, filter_section: FilterConfig, gravity: GravityConfig,
                    limits: LimitsConfig, tare: TareConfig, period_s: float, model: StiffnessModel,
                    faults: FaultMonitor, dynamics: Dynamics | None = None,
                    accelerometer: Accelerometer | None = None) -> Compensator:
        """Each part from its own section: ``model``, ``filter``, ``gravity``, ``limits``, ``tare`` (and the
        dynamic compensation built from ``dynamics``, the accelerometer from ``accelerometer``)."""
        predictor = FastPredictor.from_config(model_section, model, dynamics)
        compensator = GravityCompensator.from_config(gravity)
        return cls(predictor, SosLowPass.from_config(filter_section, period_s),
                   SpikeRejector.from_config(filter_section.spike), compensator,
                   CorrectionLimiter.from_config(limits, period_s), faults, tare.max_force_N,
                   PayloadSelector.from_config(gravity, compensator, predictor, faults), dynamics, accelerometer)

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
              hold: bool, reset: bool = False, payload_index: int = 0, inputs=None) -> None:
        """One cycle at ``t`` (s); the limited joint correction is then `correction` (deg, six floats), and every
        output of the cycle is in `vector`.

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
        if self.dynamics is not None and self.feeds and inputs is not None:
            self.dynamics.feed(t, inputs, pred.p_tcp)
        k = self.kernel
        pk = None if k is None else pred.kernel
        if k is not None and pk is None and k.bound:    # a model reload's ramp: the Python path takes over
            k.unbind(self)
        moved = q_deg is not None               # the steps both paths take first
        if moved:
            self.q_rad = np.array(q_deg) * DEG_TO_RAD
            if pk is None:
                pred.kinematics(self.q_rad)
            else:                               # the compiled call forms the kinematics, after the payload's update
                k.q[:] = self.q_rad
                pred.moved_to(self.q_rad)
        if tare:
            self._tare_pending = True
        if reset:
            pred.reset_history()
            self.tare_refused = False
        payload_moved = self.payloads.update(dt, payload_index)
        if reading is not None:
            self.samples += 1
            self.sample_t = t
        if pk is None:
            self._cycle_python(pred, dt, reading, hold, payload_moved)
        else:
            self._cycle_compiled(k, pk, pred, dt, reading, hold, moved, payload_moved)
        acc = self.accelerometer
        if acc is not None and (inputs is not None or acc.replay is not None):    # the sensor's axes at these joints
            acc.update(t, inputs, pred.R_s, tare)
            if self.dynamics is not None:                 # for the next cycle's observer
                self.dynamics.feed_motion(acc.acceleration, acc.ok, pred.p_tcp, acc.sample_period_s)

    def _cycle_compiled(self, k, pk, pred, dt: float, reading: Reading | None, hold: bool, moved: bool,
                        payload_moved: bool) -> None:
        """`cycle` on the compiled path after the steps both paths take first: the arithmetic in one compiled
        call (the kinematics in it when the joints moved); the state of the stages lives in k
        (`service.kernel.compensator`)."""
        b, lim = k.bound, self.limiter
        # a reload's swap releases the stages before it replaces them or their parameters (`release_stages`),
        # and a stage replaced otherwise is seen here: they are bound (again) for this cycle
        if not b or lim is not b[2] or self.filter is not b[1] or self.spikes is not b[0]:
            k.rebind(self)
        if pk is not self._pk:                  # another predictor (a reload's): the wrench goes on from here
            pk.ws[:] = self.wrench_sensor
            self._pk = pk
        fresh = gravity_on = False
        if reading is not None:
            if self.have_sample and not self._tare_pending:
                x = k.x_in
                x[0], x[1], x[2], x[3], x[4], x[5] = reading.wrench
                fresh = True
            else:                               # the first sample, or a tare: in steps, as the Python path
                if moved:
                    pred.kinematics(self.q_rad)
                    moved = False
                self._sample_in_steps(k, pred, reading.wrench)
            gravity_on = True
        elif payload_moved and self.have_sample:    # a switch's ramp goes on between samples too
            gravity_on = True
        flags = ((_MOVED if moved else 0) | (_FRESH if fresh else 0) | (_GRAVITY if gravity_on else 0)
                 | (_SAFE if safe_state(self.faults.word, hold, self.have_sample) else 0))
        bits = pk._cycle(pk.F, pk.I, k.S, self.vector, flags, dt)
        if not bits & 1:
            self.trip_not_finite()
        lim.safe = bits & 2 != 0
        self.ramping = bits & 4 != 0

    def _cycle_python(self, pred, dt: float, reading: Reading | None, hold: bool, moved: bool) -> None:
        """`cycle` on the Python path (the reference), after the steps both paths take first (``moved``: the
        payload's switch moved)."""
        if reading is not None:
            x = self.spikes.update(reading.wrench)
            if not self.have_sample:
                self.filter.state = self.filter.steady_state(x)
                self.have_sample = True
                pred.reset_history()
            self.filtered = filtered = self.filter.update(x)
            if self._tare_pending:
                self._tare_pending = False
                self._tare(filtered)
            ws = self.gravity.compensate(filtered, pred.R_s)
        elif moved and self.have_sample:        # a switch's ramp goes on between samples too: no catch-up step
            ws = self.gravity.compensate(self.filtered, pred.R_s)
        else:
            ws = self.wrench_sensor
        wb = pred.wrench_base(ws)
        dX = pred.deflection(wb, dt)
        dq = pred.correction(self.q_rad, dX)
        dq_deg = (dq * RAD_TO_DEG).tolist()
        target = dq_deg
        if not math.isfinite(sum(dq_deg)):          # NaN and inf propagate through the sum
            self.trip_not_finite()
            target = [0.0] * 6
        safe = safe_state(self.faults.word, hold, self.have_sample)
        self.vector[:] = self.limiter.update(dt, target, safe) + dq_deg + wb + ws + (dX * _OUT_SCALE).tolist()
        self.ramping = self.limiter.ramping

    def _sample_in_steps(self, k, pred, wrench: list[float]) -> None:
        """The first sample (the filter starts in its steady state) or a tare's: conditioned apart, the tare
        applied; the compiled call then goes on from the filtered sample (k.y)."""
        if not self.have_sample:
            k.unbind(self)
            x = self.spikes.update(wrench)
            self.filter.state = self.filter.steady_state(x)
            self.have_sample = True
            pred.reset_history()
            self.filter.update(x)
            k.bind(self)                        # the filtered sample too (filter.last_output)
        else:
            self.filter.last_output = k.condition(wrench)
        self.filtered = self.filter.last_output
        if self._tare_pending:
            self._tare_pending = False
            self._tare(self.filtered)

    def trip_not_finite(self) -> None:
        """The fault of a cycle whose correction is not finite (it then ramps to zero as in any fault)."""
        self.faults.trip(Fault.VALUE_INVALID, "the predicted correction is not finite")

    def release_stages(self) -> None:
        """The compiled path's state back into the stage objects, which a reload reads and may replace (their
        parameters too); the next compiled cycle binds them again. Whatever changes a stage's parameters
        calls this first."""
        if self.kernel is not None and self.kernel.bound:
            self.kernel.unbind(self)


class Cycle:
    """Supervision, then the signal path: one whole cycle of the service.

    Parameters
    ----------
    supervisor : Supervisor
    compensator : Compensator
        Both share one `FaultMonitor`.

    vector : (SIGNAL_SIZE,) float array, optional
        Where the cycle keeps its `Signals` (`vector`); by default an array of its own.
    """

    def __init__(self, supervisor: Supervisor, compensator: Compensator, vector: np.ndarray | None = None):
        self.supervisor = supervisor
        self.compensator = compensator
        self.faults = compensator.faults
        self.stopping = False           # the stop request: ramp to zero, then the task ends
        self.reloads = 0                # accepted reloads, counted by the reload's swap (service.reload)
        # the last cycle's Signals as one vector (SIGNAL_SLOTS), filled by every cycle on either path; the
        # compiled service packs the PLC's registers and the trace from it
        self.vector = np.zeros(SIGNAL_SIZE) if vector is None else vector
        compensator.attach(self.vector[VECTORS_START:VECTORS_START + VECTORS_SIZE])
        self._scalars = memoryview(self.vector).cast("B").cast("d")

    @classmethod
    def from_config(cls, cfg, model: StiffnessModel, vector: np.ndarray | None = None) -> Cycle:
        """The cycle as the service config composes it: each part is handed its own section."""
        faults = FaultMonitor(cfg.commander)
        period = cfg.cycle.period_ms / 1000.0
        dynamics = Dynamics(cfg.dynamics, period, cfg.resolve)
        if dynamics.active:
            log.info("%s", dynamics.describe())
        return cls(Supervisor.from_config(cfg.faults, faults, model.robot.limits_deg, cfg.cycle_enables_on_start),
                   Compensator.from_config(cfg.model, cfg.filter, cfg.gravity, cfg.limits, cfg.tare, period,
                                           model, faults, dynamics if dynamics.active else None,
                                           Accelerometer(cfg.accelerometer, cfg.gravity.g_mps2, cfg.resolve)), vector)

    def step(self, t: float, reading: Reading | None, errors: list[SensorError], command: int,
             plc_heartbeat: int, q_deg: list[float], overrun: bool = False, payload_index: int = 0,
             inputs=None) -> list[float]:
        """Run one cycle at time ``t`` (s); returns the limited joint correction (deg, six floats). ``inputs``:
        the PLC's whole `FromPlc` record (the dynamic compensation's feedforward reads its plan there)."""
        self.advance(t, reading, errors, command, plc_heartbeat, q_deg, overrun, payload_index, inputs)
        return self.compensator.correction

    def advance(self, t: float, reading: Reading | None, errors: list[SensorError], command: int,
                plc_heartbeat: int, q_deg: list[float], overrun: bool = False, payload_index: int = 0,
                inputs=None) -> None:
        """`step` without its return (the service's cycle reads `vector`)."""
        s = self.supervisor.update(t, command, plc_heartbeat, q_deg, overrun, errors)
        comp = self.compensator
        comp.cycle(t, reading, s.q_deg, s.tare, not s.enabled or self.stopping, s.reset, payload_index, inputs)
        word = self.faults.word
        status = status_word(word, comp.limiter.safe, comp.ramping, comp.have_sample, self.supervisor.plc_seen,
                             comp.tare_refused)
        age = sample_age_ms(comp.t_prev, math.nan if comp.sample_t is None else comp.sample_t, comp.t_first)
        acc = comp.accelerometer
        if acc is not None and acc.ok:
            status |= int(Status.ACCELEROMETER_OK)
        v = self._scalars
        v[_STATUS], v[_FAULT], v[_TARES], v[_SAMPLES] = status, word, comp.tares, comp.samples
        v[_AGE], v[_PAYLOAD], v[_RELOADS] = age, comp.payloads.active.index, self.reloads & 0xFFFF
        if acc is not None:
            v[_ACC], v[_ACC + 1], v[_ACC + 2] = acc.acceleration
            v[_BOX], v[_BOX + 1], v[_BOX + 2] = acc.f
            v[_BOX_SAMPLES] = acc.taken & 0xFFFF

    def signals(self) -> Signals:
        """The record of the last cycle."""
        c = self.compensator
        return Signals(self.status_word, self.faults.word, c.correction, c.dq_deg, c.wrench_base,
                       c.wrench_sensor, c.deflection, c.tares, c.samples, float(self.vector[_AGE]),
                       c.payloads.active.index, self.reloads & 0xFFFF, *(float(a) for a in self.vector[_ACC:_ACC + 3]),
                       *(float(a) for a in self.vector[_BOX:_BOX + 3]), int(self.vector[_BOX_SAMPLES]))

    @property
    def status_word(self) -> int:
        """The last cycle's status word (`Status` bits)."""
        return int(self.vector[_STATUS])

    # what a test or a log reads of the last cycle (the signal path's values)
    correction = property(lambda self: self.compensator.correction)
    dq_deg = property(lambda self: self.compensator.dq_deg)
    wrench_base = property(lambda self: self.compensator.wrench_base)
    wrench_sensor = property(lambda self: self.compensator.wrench_sensor)
    deflection = property(lambda self: self.compensator.deflection)
    tares = property(lambda self: self.compensator.tares)
