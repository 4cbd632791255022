"""The flange accelerometer: the arm's acceleration at the tool, in base axes, gravity and bias removed
(docs/accelerometer.md).

A cell reads the box (Beckhoff EP3751: a 3-axis accelerometer on EtherCAT) in its PLC; the generated library
scales its process data and passes it through the contract (`plc_link.contract.ACCELEROMETER`): ``acc_x``,
``acc_y``, ``acc_z`` in m/s^2 along the box's axes, and ``acc_samples``, the new valid samples the PLC saw. A
MEMS accelerometer measures the specific force f = R^T (a - g) (R: the box's axes in the base, g: gravity,
``gravity.g_mps2``), plus its bias b, so the arm's acceleration is

    a = R (f - b) + g,      R = R_s R_m

with R_s the force sensor's axes in the base at the joints the PLC sent (the pose is known, as for the
wrench's gravity) and R_m the box's axes in the sensor's (``accelerometer.mount``). The bias is taken as the
wrench's is: a tare (the arm at rest) sets b = f + R^T g, with f the readings through a low-pass of
``TARE_TAU_S`` (as the wrench's tare takes the filtered wrench: a servo holding its joints still moves by
micrometres, and one value would carry that), so the acceleration reads zero on average then. The lever arm
between the box and the TCP is left out: the arm's low modes translate the tool (docs/accelerometer.md).

A configured accelerometer is supervised: ``acc_samples`` unchanged for ``timeout_ms`` (the box silent, its
values invalid, or the PLC no longer passing them) or a value not finite or beyond any box's range
(`MAX_MPS2`) is the named condition ``accelerometer_frozen`` (``accelerometer_missing`` before the first
sample), logged once when it starts and once when it ends, and the status bit ``accelerometer_ok`` is clear.
It is not a latched fault: the correction goes on without the acceleration (the parts that use it fall back to
the force alone), and the acceleration reads zero meanwhile. A tare while it is not ok keeps the bias.

``accelerometer.replay`` reads the box's samples from a file instead of the PLC (`BoxReplay`): a CSV of ``t_s``,
``acc_x``, ``acc_y``, ``acc_z`` (s; m/s^2 along the box's axes, as the PLC passes them), or the service's own
trace of a cut (its ``box_`` columns: the reading taken, as it came, and the count of readings taken, `taken`),
released on the cycle's clock from its first cycle, as `service.sources.replay` releases the force sensor's CAN
log. Each sample counts as one new value, so the same supervision holds: after the file's last sample the box
reads frozen, and the correction goes on from the force alone.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
from pydantic import Field, model_validator

from stiffness.data.trace_file import looks_like_trace, read_trace
from stiffness.dynamics.records import check_whole, read_columns
from stiffness.files.yaml_schema import Strict
from stiffness.kinematics.robot import PoseConfig

log = logging.getLogger("stiffcomp.service")

FROZEN, MISSING = "accelerometer_frozen", "accelerometer_missing"
TARE_TAU_S = 0.05        # the readings' low-pass for the tare
PERIOD_TAU_S = 0.1       # the time between new values is averaged over about this
MAX_MPS2 = 400.0         # beyond any box's range (the EP3751's INT16 in mg: 32.8 g, 321 m/s^2): not a reading


class AccelerometerConfig(Strict):
    """``accelerometer``: the flange accelerometer (module docstring)."""

    enabled: bool = False
    mount: PoseConfig = Field(default_factory=PoseConfig)      # the box's axes in the force sensor's frame
    timeout_ms: float = Field(20.0, gt=0.0, le=1000.0)
    replay: str | None = None           # the box's samples (a CSV, or a trace), read in place of the PLC's values

    @model_validator(mode="after")
    def _replay_read(self):
        if self.replay and not self.enabled:
            raise ValueError(f"replay = {self.replay!r} is read only with enabled: true (the accelerometer is off)")
        return self


REPLAY_COLUMNS = ("t_s", "acc_x", "acc_y", "acc_z")


class BoxReplay:
    """The box's samples from a file (module docstring): `at` gives the count of samples released by cycle time
    ``t`` and the newest of them, as the PLC's ``acc_samples`` and ``acc_x..z``. The file is a CSV of
    `REPLAY_COLUMNS`, or a service's trace (`stiffness.data.trace_file`): its readings (`Trace.box_readings`),
    from its first row's time, so a cut traced with its box runs again with the same readings at the same cycle
    times (in real time, a late cycle takes the newer of two).
    DataError names the file, line and column of a bad file, or its last line where the file was cut off."""

    def __init__(self, path):
        self.path = str(path)
        if looks_like_trace(path):
            trace = read_trace(path)
            t, v = trace.box_readings()
            # the first line starts the clock and the count (never taken as a reading, as the PLC's first count)
            t_s, values = np.r_[trace.time_s[0], t], np.vstack([v[:1], v])
        else:
            check_whole(path)
            cols = read_columns(path, REPLAY_COLUMNS, what="replay of the accelerometer")
            t_s, values = cols["t_s"], np.column_stack([cols[c] for c in REPLAY_COLUMNS[1:]])
        # plain lists: one step of a cursor a cycle (numpy's scalar access costs more than the search)
        self.t_s = (t_s - t_s[0]).tolist()
        self.values = [tuple(v) for v in values.tolist()]
        self._t0: float | None = None
        self._n = 1                                  # the samples released: the first at the first cycle

    def at(self, t: float) -> tuple[int, tuple[float, float, float]]:
        if self._t0 is None:
            self._t0 = t
        since, times, n = t - self._t0, self.t_s, self._n
        while n < len(times) and times[n] <= since:
            n += 1
        self._n = n
        return n, self.values[n - 1]


class Accelerometer:
    """The accelerometer of one ``accelerometer`` section; `update` each cycle with the PLC's record (or, with
    ``replay``, the file's samples: `BoxReplay`)."""

    def __init__(self, section: AccelerometerConfig, g_mps2, resolve=Path):
        self.enabled = section.enabled
        self.replay = BoxReplay(resolve(section.replay)) if section.replay else None
        if self.replay is not None:
            r = self.replay
            log.info("accelerometer: replaying %s (%d samples over %.3f s) in place of the PLC's values", r.path,
                     len(r.t_s), r.t_s[-1])
        self.R_m = np.asarray(section.mount.matrix())[:3, :3]
        self.timeout_s = section.timeout_ms / 1000.0
        self.g = np.asarray(g_mps2, dtype=float)
        self.bias = np.zeros(3)
        self.f = np.zeros(3)                 # the last good reading, box axes
        self.f_lp = None                     # ... through a low-pass of TARE_TAU_S (the tare's)
        self.acceleration = np.zeros(3)      # base axes, m/s^2: zero while not ok
        self.ok = False
        self.condition: str | None = None    # FROZEN or MISSING while not ok, None otherwise
        self.sample_period_s = math.inf      # the time between new values, averaged (PERIOD_TAU_S)
        self._count: float | None = None
        self.taken = 0                       # readings taken since start: one more in each cycle that takes one
        self._moved_t: float | None = None
        self._t_first: float | None = None

    def update(self, t: float, inputs, R_sensor, tare: bool) -> None:
        """The cycle at ``t`` (s): the PLC's `FromPlc` record ``inputs`` (unread with a replay), the force
        sensor's axes in the base ``R_sensor`` (3, 3) at its joints; ``tare``: take the bias now (the arm at
        rest)."""
        if not self.enabled:
            return
        if self._t_first is None:
            self._t_first = t
        if self.replay is not None:
            count, f = self.replay.at(t)
        else:
            count, f = inputs.acc_samples, (inputs.acc_x, inputs.acc_y, inputs.acc_z)
        finite = all(math.isfinite(v) and abs(v) <= MAX_MPS2 for v in f)
        if self._count is None:                      # the first cycle: where the count stands
            self._count = count
        elif count != self._count and finite:        # a new sample
            self.f = np.array(f)
            since = t - (self._moved_t if self._moved_t is not None else t)
            w = 1.0 - math.exp(-since / TARE_TAU_S)
            self.f_lp = self.f.copy() if self.f_lp is None else self.f_lp + w * (self.f - self.f_lp)
            if self._moved_t is not None:
                p = self.sample_period_s
                self.sample_period_s = since if math.isinf(p) else p + (since - p) * min(1.0, since / PERIOD_TAU_S)
            self._count, self._moved_t = count, t
            self.taken += 1
        R = np.asarray(R_sensor) @ self.R_m
        since = t - (self._t_first if self._moved_t is None else self._moved_t)
        ok = self._moved_t is not None and finite and since <= self.timeout_s
        if tare and ok:                              # a frozen box's last value is no zero
            self.bias = self.f_lp + R.T @ self.g
            log.info("accelerometer tared: bias %s m/s^2 (box axes)", np.array2string(self.bias, precision=3))
        condition = None if ok or since <= self.timeout_s and finite else MISSING if self._moved_t is None else FROZEN
        if condition != self.condition:
            self._say(condition, since, finite)
        self.ok = ok
        self.acceleration = R @ (self.f - self.bias) + self.g if ok else np.zeros(3)

    def _say(self, condition: str | None, since: float, finite: bool) -> None:
        """Log the condition's start (named, with why) or its end, once each."""
        if condition is None:
            log.info("%s ended: the accelerometer's samples arrive again", self.condition)
        else:
            held = ("acc_samples has not moved" if self.replay is None else
                    f"no new sample of {self.replay.path} (its last at {self.replay.t_s[-1]:.3f} s)")
            why = (f"a value is not finite or beyond {MAX_MPS2:g} m/s^2" if not finite else
                   f"{held} for {1000 * since:.0f} ms (accelerometer.timeout_ms = {1000 * self.timeout_s:g})")
            log.warning("%s: %s; the correction goes on from the force alone", condition, why)
        self.condition = condition
