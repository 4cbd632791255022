"""One cycle of the compensation, as a pure function of time and inputs (no clock, no I/O).

    sample -> spike rejection -> low-pass -> gravity compensation -> base axes -> deflection (model)
           -> δq (Jacobian pseudo-inverse) -> limits -> outputs

`Compensator.cycle(t, ...)` takes the time and every input as arguments, so a replay or a test
drives it exactly as the live loop does.
"""

from __future__ import annotations

import logging
import math

import numpy as np

from stiffness.model import StiffnessModel
from stiffness.units import DEG_TO_RAD, M_TO_MM, RAD_TO_DEG

from .ati import Reading
from .compensation import FastPredictor
from .errors import SensorError
from .faults import FaultMonitor
from .filters import SosLowPass, SpikeRejector
from .gravity import GravityCompensator
from .limits import CorrectionLimiter

log = logging.getLogger("stiffcomp.service")

CMD_ENABLE, CMD_TARE, CMD_RESET = 0x1, 0x2, 0x4
ST_RUNNING, ST_ACTIVE, ST_FAULTED, ST_RAMPING, ST_SENSOR_OK, ST_PLC_SEEN, ST_STOPPED = (
    0x1, 0x2, 0x4, 0x8, 0x10, 0x20, 0x40)
_OUT_SCALE = np.array([M_TO_MM, M_TO_MM, M_TO_MM, RAD_TO_DEG, RAD_TO_DEG, RAD_TO_DEG])


class Compensator:
    """The signal path and its safety logic.

    Parameters
    ----------
    predictor, filter, spikes, gravity, limiter : the stages
    joint_limits_deg : (6, 2)
    heartbeat_timeout_s : float
        0 switches the PLC heartbeat supervision off.
    overrun_trip_count : int
        Consecutive overruns that trip the overrun fault.
    enable_on_start : bool
        Act as if the enable bit were set (demo and bench without a PLC).
    """

    def __init__(self, predictor: FastPredictor, filter: SosLowPass, spikes: SpikeRejector,
                 gravity: GravityCompensator, limiter: CorrectionLimiter, joint_limits_deg: np.ndarray,
                 heartbeat_timeout_s: float, overrun_trip_count: int, enable_on_start: bool = False):
        self.predictor = predictor
        self.filter = filter
        self.spikes = spikes
        self.gravity = gravity
        self.limiter = limiter
        self.lo = [float(v) for v in joint_limits_deg[:, 0]]
        self.hi = [float(v) for v in joint_limits_deg[:, 1]]
        self.hb_timeout = float(heartbeat_timeout_s)
        self.overrun_trip = int(overrun_trip_count)
        self.enable_on_start = enable_on_start
        self.faults = FaultMonitor()
        self.prev_command = 0
        self.prev_hb: int | None = None
        self.hb_change_t = 0.0
        self.plc_seen = False
        self.overruns = 0
        self.t_prev: float | None = None
        self.have_sample = False
        self.wrench_sensor = [0.0] * 6        # filtered, gravity-compensated, sensor axes (N, Nm)
        self.wrench_base = [0.0] * 6          # the same in base axes, moment about the sensor origin
        self.deflection = [0.0] * 6           # predicted TCP deflection, mm and deg, base axes
        self.dq_deg = [0.0] * 6               # δq before limits, deg
        self.correction = [0.0] * 6           # δq after limits, deg
        self.q_rad = np.zeros(6)
        self._q_last: list[float] | None = None
        self.status_word = 0
        self.tares = 0
        self._tare_pending = False            # a tare edge waits for the next sample
        self.stopping = False                 # set by the service on stop: safe until the task ends

    @classmethod
    def from_config(cls, cfg, model: StiffnessModel) -> Compensator:
        period = cfg.cycle.period_ms / 1000.0
        return cls(FastPredictor.from_config(cfg.model, model), SosLowPass.from_config(cfg.filter, period),
                   SpikeRejector.from_config(cfg.filter.spike), GravityCompensator.from_config(cfg.gravity),
                   CorrectionLimiter.from_config(cfg.limits, period), model.robot.limits_deg,
                   cfg.faults.plc_heartbeat_timeout_ms / 1000.0, cfg.faults.overrun_trip_count,
                   cfg.plc.enable_on_start)

    # -- one cycle ------------------------------------------------------------------------------
    def cycle(self, t: float, reading: Reading | None, errors: list[SensorError], command: int,
              plc_heartbeat: int, q_deg: list[float], overrun: bool = False) -> list[float]:
        """Run one cycle at time ``t`` (s); returns the limited joint correction (deg, six floats)."""
        dt = 0.0 if self.t_prev is None else t - self.t_prev
        self.t_prev = t
        faults = self.faults
        rising = command & ~self.prev_command
        self.prev_command = command
        if rising & CMD_RESET:
            faults.reset()
            self.overruns = 0
        for e in errors:              # after the reset: a reset clears only faults whose cause is gone
            faults.trip_error(e)
        enabled = bool(command & CMD_ENABLE) or self.enable_on_start
        self._supervise_plc(t, plc_heartbeat, bool(rising & CMD_ENABLE), bool(command & CMD_ENABLE))
        self._supervise_overrun(overrun)
        if q_deg != self._q_last and self._check_q(q_deg):
            # kinematics only when q changes (exact comparison: a cache that never approximates)
            self.q_rad = np.array(q_deg) * DEG_TO_RAD
            self.predictor.kinematics(self.q_rad)
            self._q_last = list(q_deg)
        pred = self.predictor
        R_s = pred.R_s
        if rising & CMD_TARE:
            self._tare_pending = True
        if reading is not None:
            x = self.spikes.update(reading.wrench)
            if not self.have_sample:
                self.filter.state = self.filter.steady_state(x)
                self.have_sample = True
            filtered = self.filter.update(x)
            if self._tare_pending:
                self._tare_pending = False
                self.gravity.tare(filtered, R_s)
                self.tares += 1
                log.info("tare: bias is now %s", np.array2string(self.gravity.bias, precision=2))
            self.wrench_sensor = self.gravity.compensate(filtered, R_s)
        self.wrench_base = pred.wrench_base(self.wrench_sensor)
        dX = pred.deflection(self.wrench_base)
        dq = pred.correction(self.q_rad, dX)
        self.deflection = (dX * _OUT_SCALE).tolist()
        self.dq_deg = dq_deg = (dq * RAD_TO_DEG).tolist()
        if not math.isfinite(sum(dq_deg)):          # NaN and inf propagate through the sum
            faults.trip("value_invalid", "the predicted correction is not finite")
            dq_deg = [0.0] * 6
        safe = faults.word != 0 or not enabled or not self.have_sample or self.stopping
        self.correction = self.limiter.update(dt, dq_deg, safe)
        self.status_word = (ST_RUNNING | (0 if safe else ST_ACTIVE) | (ST_FAULTED if faults.word else 0)
                            | (ST_RAMPING if self.limiter.ramping else 0)
                            | (ST_SENSOR_OK if self.have_sample and not faults.word & 0x1F else 0)
                            | (ST_PLC_SEEN if self.plc_seen else 0))
        return self.correction

    def _check_q(self, q_deg: list[float]) -> bool:
        for j, v in enumerate(q_deg):
            if not math.isfinite(v):
                self.faults.trip("value_invalid", f"q{j + 1} = {v} from the PLC is not finite")
                return False
            if not self.lo[j] <= v <= self.hi[j]:
                self.faults.trip("joint_limits", f"q{j + 1} = {v:.3f} deg is outside the joint limits "
                                 f"[{self.lo[j]:g}, {self.hi[j]:g}]")
                return False
        return True

    def _supervise_plc(self, t: float, hb: int, enable_rose: bool, enabled_by_plc: bool) -> None:
        if self.prev_hb is None or hb != self.prev_hb:
            if self.prev_hb is not None:
                self.plc_seen = True
            self.prev_hb = hb
            self.hb_change_t = t
        if enable_rose:
            self.hb_change_t = t          # supervision starts when the PLC enables
        if self.hb_timeout > 0 and enabled_by_plc and t - self.hb_change_t > self.hb_timeout:
            self.faults.trip("plc_heartbeat", f"plc_heartbeat unchanged for {(t - self.hb_change_t) * 1000:.0f} ms "
                             f"(timeout {self.hb_timeout * 1000:g} ms)")

    def _supervise_overrun(self, overrun: bool) -> None:
        self.overruns = self.overruns + 1 if overrun else 0
        if self.overruns >= self.overrun_trip:
            self.faults.trip("overrun", f"{self.overruns} consecutive cycles overran their period")
