"""The F/T source boundary: shared decoding, validation and timeout; backends deliver raw CAN frames.

A backend implements one hook, ``_frames(t)``: the CAN frames that have arrived by time ``t`` (s,
the service's clock) as ``(arbitration_id, data, is_error_frame)``. `FtSource.poll` decodes them
with the ATI protocol, checks every sample (status word, saturation, finite values, measuring
range) and the time since the last good sample, and returns the newest good sample with the list
of problems seen. Problems are `SensorError` instances: the fault monitor turns them into fault bits.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Iterable
from pathlib import Path

import numpy as np

from ..ati import AtiProtocol, Reading
from ..errors import (
    CanFrameError,
    SensorError,
    SensorSaturated,
    SensorStatusError,
    SensorTimeout,
    SensorValueError,
)

Frame = tuple[int, bytes, bool]


class FtSource(ABC):
    """Base of the F/T sources.

    Parameters
    ----------
    protocol : AtiProtocol
    timeout_s : float
        A source silent for longer than this reports SensorTimeout.
    max_force_N, max_torque_Nm : float
        The measuring range; a larger absolute value is a SensorValueError.
    """

    def __init__(self, protocol: AtiProtocol, timeout_s: float, max_force_N: float, max_torque_Nm: float):
        self.protocol = protocol
        self.timeout_s = float(timeout_s)
        self.max_force = float(max_force_N)
        self.max_torque = float(max_torque_Nm)
        self.last_sample_t: float | None = None
        self.t_open: float | None = None
        self.samples = 0

    @classmethod
    @abstractmethod
    def from_config(cls, section, timeout_s: float, resolve: Callable[[str], Path]) -> FtSource:
        """Build from the ``source`` section; ``timeout_s`` is ``faults.sensor_timeout_ms`` in s and
        ``resolve`` turns a path written in the config into a file."""

    @staticmethod
    def common_args(section, timeout_s: float) -> dict:
        return {"protocol": AtiProtocol.from_config(section.ati), "timeout_s": timeout_s,
                "max_force_N": section.max_force_N, "max_torque_Nm": section.max_torque_Nm}

    # -- the hook -------------------------------------------------------------------------------
    @abstractmethod
    def _frames(self, t: float) -> Iterable[Frame]:
        """CAN frames received by time ``t`` and not returned before."""

    lead_s = 0.0        # > 0: the task calls `request` this long before each cycle's deadline

    def request(self) -> None:
        """Ask for the next sample ahead of the cycle that reads it (`lead_s`; a no-op by default)."""

    def request_bias(self) -> None:
        """Ask the sensor to bias itself (a no-op for sources that cannot talk back)."""

    def close(self) -> None:
        """Release the bus or file."""

    # -- the shared logic -----------------------------------------------------------------------
    def poll(self, t: float) -> tuple[Reading | None, list[SensorError]]:
        """The newest good sample received by ``t`` (or None) and the problems seen."""
        if self.t_open is None:
            self.t_open = t
        errors: list[SensorError] = []
        newest = None
        decode = self.protocol.decode
        for arb_id, data, is_error in self._frames(t):
            if is_error:
                errors.append(CanFrameError(f"CAN error frame (id {arb_id:#05x})"))
                continue
            try:
                reading = decode(arb_id, data)
            except CanFrameError as e:
                errors.append(e)
                continue
            if reading is not None and self._check(reading, errors):
                newest = reading
        if newest is not None:
            self.last_sample_t = t
            self.samples += 1
        else:
            since = self.last_sample_t if self.last_sample_t is not None else self.t_open
            if t - since > self.timeout_s:
                errors.append(SensorTimeout(f"no sample for {(t - since) * 1000:.1f} ms "
                                            f"(timeout {self.timeout_s * 1000:g} ms)"))
        return newest, errors

    def _check(self, r: Reading, errors: list[SensorError]) -> bool:
        w, mf, mt = r.wrench, self.max_force, self.max_torque
        # a good sample passes in one expression (NaN fails every comparison, so it is told below)
        if (not r.status and not r.saturated and -mf <= w[0] <= mf and -mf <= w[1] <= mf and -mf <= w[2] <= mf
                and -mt <= w[3] <= mt and -mt <= w[4] <= mt and -mt <= w[5] <= mt):
            return True
        return self._problems(r, errors)

    def _problems(self, r: Reading, errors: list[SensorError]) -> bool:
        """Each problem of a sample that did not pass `_check`, into ``errors``; False when it is not usable."""
        ok = True
        if r.status != 0:
            errors.append(SensorStatusError(f"sensor status word {r.status:#06x} (sample {r.counter})"))
            ok = False
        if r.saturated:
            errors.append(SensorSaturated(f"a gauge channel is at the INT16 limit (sample {r.counter})"))
            ok = False
        w = r.wrench
        if not math.isfinite(sum(w)):               # NaN and inf propagate through the sum
            errors.append(SensorValueError(f"non-finite wrench {np.array2string(np.array(w), precision=3)}"))
            return False
        fmax = max(abs(w[0]), abs(w[1]), abs(w[2]))
        tmax = max(abs(w[3]), abs(w[4]), abs(w[5]))
        if fmax > self.max_force or tmax > self.max_torque:
            errors.append(SensorValueError(f"wrench out of range: |F| {fmax:.1f} N (max {self.max_force:g}), "
                                           f"|T| {tmax:.2f} Nm (max {self.max_torque:g})"))
            ok = False
        return ok
