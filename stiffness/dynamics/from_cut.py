"""The modes' record from a cut's trace: the wrench the service used and the arm's acceleration at the tool
(`stiffcomp modes TRACE --robot ROBOT`, docs/accelerometer.md, "The modes from a cut").

A trace of a service with the flange accelerometer (`service.accelerometer`) holds, every cycle, the joints
the PLC reported, the wrench in base axes and the acceleration at the tool in base axes. No path is measured:
the deflection d is seen through the accelerometer's band (`stiffness.dynamics.observer.band_sos`),

    e = (B / s^2) a - L B FK(q)  =  L B d

the acceleration double-integrated in the band B less the nominal TCP of the joints, the box's low-pass L on
the positions as on the acceleration. The record (`stiffness.dynamics.modes.Record`) carries e as its
deflection and L B as its ``band``, so the identification takes the model's response through the same
filters: the modes, their damping and directions, and the lag between the wrench and the band's deflection.
The lag so found is the arm's own lag plus the trace's: the wrench in a trace has passed the sensor's and the
service's low-pass, the acceleration the box's age at the service; `TRACE_LAG_MS` is what the HIL's 1 ms
cell adds, and `stiffcomp modes` writes the lag less it.

Only the rows whose acceleration arrived (status bit 8, `plc_link.contract.Status.ACCELEROMETER_OK`) are
used: the longest run of them, on the service's cycle, less its first `SETTLE_S` (the band's filters start
there, and their start is no motion of the arm).
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from ..data.trace_file import ACCELERATION, WRENCH, Q, Trace
from ..errors import DataError
from ..kinematics.robot import Robot
from .modes import MIN_SAMPLES, Record
from .observer import band_sos

ACCELEROMETER_OK = 0x100        # status_word's bit 8 (plc_link.contract.Status, a floor above this one)
BAND_HZ = (2.5, 40.0)
BOX_LOWPASS_HZ = 62.5
SETTLE_S = 0.4          # the band's high-pass (2.5 Hz: three poles) settles within it


def record_from_trace(trace: Trace, robot: Robot, band_hz=BAND_HZ, box_lowpass_hz: float = BOX_LOWPASS_HZ) -> Record:
    """The band's record of ``trace`` (module docstring), the nominal TCP from ``robot``'s kinematics; DataError
    naming the file when the trace holds no acceleration, or too few rows with it."""
    acc = trace.block(ACCELERATION)
    ok = (trace.column("status_word").astype(int) & ACCELEROMETER_OK) != 0
    if np.isnan(acc).all() or not ok.any():
        raise DataError(f"{trace.source}: the trace holds no acceleration (its accelerometer columns are "
                        f"{'missing' if np.isnan(acc).all() else 'never marked as arriving'}): record the cut "
                        "with accelerometer.enabled (docs/accelerometer.md)")
    edges = np.flatnonzero(np.diff(np.concatenate([[0], ok.astype(int), [0]])))
    starts, ends = edges[::2], edges[1::2]
    k = int(np.argmax(ends - starts))
    rows = slice(starts[k], ends[k])
    t = trace.column("time_s")[rows]
    period = float(np.median(np.diff(t)))
    q = np.radians(trace.block(Q)[rows])
    p = robot.frames(q)[:, 7, :3, 3]
    to_acc, to_pos = band_sos(band_hz, box_lowpass_hz, period)
    e_acc = signal.sosfilt(to_acc, acc[rows], axis=0)
    zi = signal.sosfilt_zi(to_pos)[:, :, None] * p[:1][None, :, :]
    e_pos = signal.sosfilt(to_pos, p, axis=0, zi=zi)[0]
    force = trace.block(WRENCH[:3])[rows]
    keep = t - t[0] >= SETTLE_S
    if keep.sum() < MIN_SAMPLES:
        raise DataError(f"{trace.source}: the longest run of rows with the acceleration arriving is "
                        f"{t[-1] - t[0]:.2f} s; the identification needs {SETTLE_S:g} s for the band's filters to "
                        f"settle and {MIN_SAMPLES} cycles after it")
    return Record(t[keep] - t[keep][0], force[keep], (e_acc - e_pos)[keep], f"{trace.source} (the accelerometer's band)",
                  band=to_pos)
