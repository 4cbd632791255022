"""Replay of a python-can log file (.asc, .blf, .log, .trc, .csv through can.LogReader), and writing one.

Reading and pacing are separate: `read_log` reads the whole file once at start-up; `ReplaySource`
hands the frames out either by the service's clock (``pacing: realtime``, frames whose log time has
come) or one sample per cycle (``pacing: fast``, as fast as the caller polls). With ``loop: true``
the log starts again after its last frame, shifted by its duration.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterable
from pathlib import Path
from typing import Literal

import can
import numpy as np

from stiffness.errors import quote
from stiffness.files.yaml_schema import Strict

from ..ati import AtiProtocol
from ..errors import SourceError
from .base import Frame, FtSource

LOG_SUFFIXES = (".asc", ".blf", ".log", ".trc", ".csv")


def read_log(path: str | Path) -> list[tuple[float, int, bytes, bool]]:
    """All frames of a log as (time since the first frame in s, id, data, is_error_frame)."""
    path = Path(path)
    if not path.exists():
        raise SourceError(f"{path}: replay file not found")
    if path.suffix.lower() not in LOG_SUFFIXES:
        raise SourceError(f"{path}: replay file type {quote(path.suffix)} is not one of {', '.join(LOG_SUFFIXES)}")
    frames = []
    try:
        with can.LogReader(str(path)) as reader:
            for msg in reader:
                frames.append((float(msg.timestamp), int(msg.arbitration_id), bytes(msg.data),
                               bool(msg.is_error_frame)))
    except Exception as e:  # the log readers raise many unrelated types on corrupt files
        raise SourceError(f"{path}: cannot read the CAN log: {e}") from e
    if not frames:
        raise SourceError(f"{path}: the CAN log holds no frames")
    frames.sort(key=lambda f: f[0])      # stable: a recorder may log its own requests slightly out of order
    t0 = frames[0][0]
    return [(t - t0, i, d, err) for t, i, d, err in frames]


def write_log(path: str | Path, wrench: np.ndarray, rate_hz: float = 1000.0, protocol: AtiProtocol | None = None,
              status: np.ndarray | None = None, extra: list[tuple[int, int, bytes]] | None = None) -> None:
    """Write request + answer frames for each row of ``wrench`` to a python-can log (format by suffix).

    ``extra`` adds frames (sample index, id, data) after that sample, e.g. to inject bad frames.
    """
    p = protocol or AtiProtocol()
    req_id, req = p.request_short_data()
    extra_at: dict[int, list[tuple[int, bytes]]] = {}
    for k, arb, data in extra or []:
        extra_at.setdefault(k, []).append((arb, data))
    with can.Logger(str(path)) as log:
        for k, w in enumerate(wrench):
            t = 1.0 + k / rate_hz
            log(can.Message(timestamp=t, arbitration_id=req_id, data=req, is_extended_id=False))
            st = int(status[k]) if status is not None else 0
            for j, (arb, data) in enumerate(p.encode(w, st, k)):
                log(can.Message(timestamp=t + (j + 1) * 2e-4, arbitration_id=arb, data=data, is_extended_id=False))
            for arb, data in extra_at.get(k, []):
                log(can.Message(timestamp=t + 6e-4, arbitration_id=arb, data=data, is_extended_id=False))



class ReplayConfig(Strict):
    """``source.replay``: the CAN log to replay (relative to the config file), its pacing, and looping."""

    file: str
    pacing: Literal["realtime", "fast"] = "realtime"
    loop: bool = True

class ReplaySource(FtSource):
    """F/T samples from a recorded CAN log.

    Parameters
    ----------
    frames : list of (t, id, data, is_error_frame)
        As returned by `read_log`.
    pacing : "realtime" or "fast"
    loop : bool
    name : str
        The log's file name, for error messages.

    Raises
    ------
    SourceError
        The log holds no sample frame for the configured sensor (``source.ati.base_id``): it could
        never deliver a sample.
    """

    def __init__(self, frames: list[tuple[float, int, bytes, bool]], pacing: str = "realtime", loop: bool = True,
                 name: str = "replay log", **kw):
        super().__init__(**kw)
        self.sample_id = self.protocol.id_2
        if not any(arb == self.sample_id and not err for _, arb, _, err in frames):
            raise SourceError(f"{name}: the CAN log holds no sample frame with id {self.sample_id:#05x} "
                              f"(source.ati.base_id = {self.protocol.base_id:#05x}); is base_id right?")
        self.frames = frames
        self._times = [f[0] for f in frames]
        self._hook = [f[1:] for f in frames]        # (id, data, is_error_frame): what `_frames` hands out
        self.fast = pacing == "fast"
        self.loop = loop
        gaps = [b[0] - a[0] for a, b in itertools.pairwise(frames) if b[0] > a[0]]
        self.duration = frames[-1][0] + (min(gaps) if gaps else 1e-3)
        self.next_frame = 0
        self.offset = 0.0
        self.exhausted = False

    @classmethod
    def from_config(cls, section, timeout_s: float, resolve) -> ReplaySource:
        r = section.replay
        path = resolve(r.file)
        return cls(read_log(path), r.pacing, r.loop, name=str(path), **cls.common_args(section, timeout_s))

    def _frames(self, t: float) -> Iterable[Frame]:
        frames, n = self.frames, len(self.frames)
        rel = t - (self.t_open or 0.0)
        if not self.fast and not self.exhausted:
            # the frames whose time has come (a few per cycle): one slice, unless the log ends in it
            k, times, offset = self.next_frame, self._times, self.offset
            end = k
            while end < n and times[end] + offset <= rel:
                end += 1
            if end < n:
                self.next_frame = end
                return self._hook[k:end]
        out: list[Frame] = []
        # at most one pass over the log per poll: a looped log that yields no sample must not hang the cycle
        while not self.exhausted and len(out) < n:
            ts, arb, data, err = frames[self.next_frame]
            if not self.fast and ts + self.offset > rel:
                break
            out.append((arb, data, err))
            self.next_frame += 1
            if self.next_frame == n:
                if self.loop:
                    self.next_frame = 0
                    self.offset += self.duration
                else:
                    self.exhausted = True
            if self.fast and arb == self.sample_id:
                break
        return out
