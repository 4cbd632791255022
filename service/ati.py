"""The ATI Net F/T CAN protocol (short data), encoded and decoded with `struct` for the hot path.

Requests are one-byte frames to the base ID: 0x02 asks for one sample of short data, 0x04 biases
(tares) the sensor. A short-data answer is two frames:

    base + 5:  Fx, Tx, Fy, Ty                      4 x INT16 little-endian counts
    base + 6:  Fz, Tz, status word, sample counter  2 x INT16 + 2 x UINT16 little-endian

Force = counts / counts_per_force (N); torque = counts / counts_per_torque (Nm). The same layout is
described for tools in config/ati_netft_can.dbc; `tests/service/test_ati.py` checks that the DBC
and this decoder agree.
"""

from __future__ import annotations

import struct
from typing import Literal, NamedTuple

import numpy as np
from pydantic import Field

from stiffness.files.yaml_schema import Strict

from .errors import CanFrameError

REQ_SHORT_DATA = 0x02
REQ_BIAS = 0x04
FRAME_1 = 5
FRAME_2 = 6
BLOCK = 16          # the sensor owns IDs base .. base + 15
INT16_LIMITS = (-32768, 32767)

_HALF = struct.Struct("<hhhh")
_SECOND = struct.Struct("<hhHH")


class AtiConfig(Strict):
    """``source.ati``: the sensor's CAN identifiers, counts per unit, and what a foreign frame does."""

    base_id: int = Field(0x020, ge=0, le=0x7F0)
    counts_per_force: float = Field(10.0, gt=0)
    counts_per_torque: float = Field(100.0, gt=0)
    foreign_frames: Literal["fault", "ignore"] = "fault"
    dbc: str = "ati_netft_can.dbc"


class Reading(NamedTuple):
    """One decoded sample: wrench [Fx, Fy, Fz (N), Tx, Ty, Tz (Nm)] in sensor axes, and its flags.

    The wrench is a list of six floats: the hot path works on Python floats, which for six values is
    faster than NumPy's per-call overhead. A named tuple, immutable, as one sample is; it is made in a
    third of the time a frozen dataclass takes, once per sample in the cycle.
    """

    wrench: list[float]
    status: int
    counter: int
    saturated: bool


_new = tuple.__new__        # a Reading without its Python-level __new__ (once per sample, in the cycle)


class AtiProtocol:
    """Frame layout and scaling of one ATI sensor on a CAN bus.

    Parameters
    ----------
    base_id : int
        The sensor's base CAN identifier (11 bit).
    counts_per_force, counts_per_torque : float
        Counts per N and per Nm, from the sensor's calibration.
    foreign_frames : "fault" or "ignore"
        What to do with frames outside the sensor's identifier block.
    """

    def __init__(self, base_id: int = 0x020, counts_per_force: float = 10.0, counts_per_torque: float = 100.0,
                 foreign_frames: str = "fault"):
        self.base_id = int(base_id)
        self.cpf = float(counts_per_force)
        self.cpt = float(counts_per_torque)
        self.fault_foreign = foreign_frames == "fault"
        self.id_1 = self.base_id + FRAME_1
        self.id_2 = self.base_id + FRAME_2
        self._kf, self._kt = 1.0 / self.cpf, 1.0 / self.cpt
        self._first: tuple[int, int, int, int] | None = None

    @classmethod
    def from_config(cls, section: AtiConfig) -> AtiProtocol:
        return cls(section.base_id, section.counts_per_force, section.counts_per_torque, section.foreign_frames)

    # -- requests -------------------------------------------------------------------------------
    def request_short_data(self) -> tuple[int, bytes]:
        return self.base_id, bytes([REQ_SHORT_DATA])

    def request_bias(self) -> tuple[int, bytes]:
        return self.base_id, bytes([REQ_BIAS])

    # -- answers --------------------------------------------------------------------------------
    def encode(self, wrench: np.ndarray, status: int = 0, counter: int = 0) -> list[tuple[int, bytes]]:
        """The two answer frames for a wrench (N, Nm); counts are rounded and clipped to INT16."""
        w = np.asarray(wrench, dtype=float)
        c = np.clip(np.round(np.concatenate([w[:3] * self.cpf, w[3:] * self.cpt])), *INT16_LIMITS).astype(int)
        fx, fy, fz, tx, ty, tz = (int(v) for v in c)
        return [(self.id_1, _HALF.pack(fx, tx, fy, ty)),
                (self.id_2, _SECOND.pack(fz, tz, status & 0xFFFF, counter & 0xFFFF))]

    def decode(self, arbitration_id: int, data: bytes) -> Reading | None:
        """Feed one received frame; return a Reading when the second half of a sample arrives.

        Raises CanFrameError for a frame of the wrong length or an identifier the protocol does not
        define (inside the sensor's block, or anywhere when ``foreign_frames`` is "fault").
        """
        if arbitration_id == self.id_1:
            if len(data) != 8:
                raise CanFrameError(f"CAN id {arbitration_id:#05x}: {len(data)} data bytes, short data has 8")
            self._first = _HALF.unpack(data)
            return None
        if arbitration_id == self.id_2:
            if len(data) != 8:
                raise CanFrameError(f"CAN id {arbitration_id:#05x}: {len(data)} data bytes, short data has 8")
            first, self._first = self._first, None
            if first is None:
                return None  # the first half was lost (e.g. the log starts mid-sample): wait for the next
            fz, tz, status, counter = _SECOND.unpack(data)
            fx, tx, fy, ty = first
            # a gauge at either INT16 limit; `in` on the tuples runs in C (the status word and the counter are
            # unsigned, so only the forces' and torques' fields of the second frame are asked)
            saturated = -32768 in first or 32767 in first or fz in INT16_LIMITS or tz in INT16_LIMITS
            kf, kt = self._kf, self._kt
            return _new(Reading, ([fx * kf, fy * kf, fz * kf, tx * kt, ty * kt, tz * kt], status, counter, saturated))
        if arbitration_id == self.base_id:
            return None  # a request (ours, or recorded in a log)
        if self.base_id <= arbitration_id < self.base_id + BLOCK:
            raise CanFrameError(f"CAN id {arbitration_id:#05x} is not defined by the ATI short-data protocol "
                                f"(base {self.base_id:#05x})")
        if self.fault_foreign:
            raise CanFrameError(f"CAN id {arbitration_id:#05x} is foreign to the sensor's bus "
                                f"(ids {self.base_id:#05x}..{self.base_id + BLOCK - 1:#05x})")
        return None
