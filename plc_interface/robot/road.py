"""The robot road: each packet of the robot's real-time interface answered at once from the process image.

The robot is the clock. `RobotRoad.received` runs for every datagram, in the I/O process's loop:

1. a packet from an address other than ``robot.peer`` changes nothing (counted, logged once per address);
2. the packet is read (`rsi.parse`, `egm.parse`); a malformed one, a stamp (IPOC, seqno) that does not rise,
   or joints that are not finite or outside the robot's limits are counted and dropped, unanswered;
3. the programmed joints go into the image's ``q1..q6`` (for RSI's setpoints, the correction the robot
   already holds is taken off first), as a PLC's joints do. With ``plc.role: none`` the road also writes the
   command word (the robot's own, else enable as ``plc.enable_on_start`` says) and steps ``plc_heartbeat``:
   a robot that falls silent for ``faults.plc_heartbeat_timeout_ms`` latches the heartbeat fault and the
   correction ramps, as for a lost PLC;
4. the answer is the newest correction the cycle published, never waiting for the cycle.

A robot that speaks again after such a silence starts a new session: the road raises the reset bit (as a
PLC does after a lost link) and answers from zero correction, ramping in over ``limits.fault_ramp_s``.
"""

from __future__ import annotations

import asyncio
import logging
import time
from dataclasses import dataclass, field

import numpy as np

from ..contract import Command
from ..errors import PlcError
from ..ratelog import RateLimitedLog
from .answers import Answerer
from .packets import PacketError
from .settings import RobotSettings

log = logging.getLogger("stiffcomp.robot")

LATENCY_RING = 1 << 16
RESET_HOLD_S = 0.25         # the reset bit is held while faults remain, this long at most (as the HIL's PLC)
_ENABLE, _RESET = int(Command.ENABLE), int(Command.RESET)


@dataclass
class RoadSettings:
    """What the road needs beyond the ``robot`` section, from the rest of the service config."""

    robot: RobotSettings
    owns_commands: bool = True          # plc.role none: the robot's packets are the command word and heartbeat
    enable_on_start: bool = False
    silence_s: float = 0.2              # faults.plc_heartbeat_timeout_ms (a quiet robot's new session)
    ramp_s: float = 0.2                 # limits.fault_ramp_s (the answer ramps in from zero)
    limits_deg: list[tuple[float, float]] = field(default_factory=lambda: [(-360.0, 360.0)] * 6)
    robot_file: str | None = None       # the model's robot, for the TCP motion of a Cartesian answer


class RobotRoad:
    """The robot interface as a part of the I/O server (`plc_interface.io_server.IoServer`).

    Parameters
    ----------
    image : ProcessImage
    settings : RoadSettings
    metrics : ServiceMetrics or None
    clock : monotonic seconds
    """

    protocol = "robot"

    def __init__(self, image, settings: RoadSettings, metrics=None, clock=time.monotonic):
        self.image, self.settings, self.metrics, self.clock = image, settings, metrics, clock
        r = settings.robot
        self.answerer = Answerer(r, settings.robot_file)
        self.transport = None
        self.errors = RateLimitedLog(log, 10.0)
        self.counts = {"packets": 0, "answered": 0, "sessions": 0, "late_reported": 0, "stamp_gaps": 0,
                       "slow_answers": 0, "dropped": {}}
        self.latency_us = np.zeros(LATENCY_RING)
        self._n_latency = 0
        self.heartbeat = 0
        self._strangers: set[str] = set()
        self._last_t: float | None = None
        self._session_t = 0.0
        self._last_stamp: int | None = None
        self._last_late: int | None = None
        self._slow_ns = r.cycle_ms * 1_000_000
        self._in = image.in_codec.index
        self._q_names = [f"q{i}" for i in range(1, 7)]

    # -- life cycle -------------------------------------------------------------------------------
    async def start(self) -> None:
        r = self.settings.robot
        warning = r.exposure_warning()
        if warning:
            log.warning(warning)
        loop = asyncio.get_running_loop()
        try:
            self.transport, _ = await loop.create_datagram_endpoint(lambda: _Datagrams(self),
                                                                    local_addr=(r.host, r.port))
        except OSError as e:
            from ..listen import explain

            raise PlcError(f"cannot listen for the robot on {r.host}:{r.port}: "
                           f"{explain(e, r.host, r.port, 'robot.port', 'udp')}") from e
        log.info("robot road: %s%s", r.served(), f", packets from {r.peer} only" if r.peer else "")

    async def stop(self) -> None:
        if self.transport is not None:
            self.transport.close()
            self.transport = None
        self.errors.flush()

    @property
    def clients(self) -> int:
        return int(self._last_t is not None and self.clock() - self._last_t <= self.settings.silence_s)

    # -- one datagram -------------------------------------------------------------------------------
    def received(self, data: bytes, addr) -> bytes | None:
        """The answer to one datagram from ``addr``, or None (dropped: counted, and logged at a limited rate)."""
        self.counts["packets"] += 1
        peer = str(addr[0])
        if not self.settings.robot.takes(peer):
            if peer not in self._strangers and len(self._strangers) < 256:
                self._strangers.add(peer)
                log.warning("robot road: a packet from %s, not robot.peer %s: dropped (further ones are only counted)",
                            peer, self.settings.robot.peer)
            self._drop("peer")
            return None
        try:
            p = self.answerer.parse(data)
            now = self.clock()
            new = self._last_t is None or now - self._last_t > self.settings.silence_s
            if not new and self._last_stamp is not None and p.stamp <= self._last_stamp:
                raise PacketError("stamp", f"stamp {p.stamp} does not rise (last {self._last_stamp})")
            missed = 0 if new else self._missed(p)
            q = self.answerer.programmed(p.joints_deg, new, missed)
            self._check_limits(q)
        except PacketError as e:
            self.errors.report(peer, e.reason, str(e))
            self._drop(e.reason)
            return None
        if new:                             # only a packet taken begins a session
            self._new_session(now)
        elif missed:
            self.answerer.missed(missed)
        self._note_counts(p)
        self._last_t, self._last_stamp = now, p.stamp
        out = self.image.outputs()
        self._write_inputs(p, q, now, out)
        ramp = min(1.0, (now - self._session_t) / self.settings.ramp_s) if self.settings.ramp_s > 0 else 1.0
        correction = [ramp * out[f"correction_q{i}"] for i in range(1, 7)]
        self.counts["answered"] += 1
        return self.answerer.answer(p, q, correction, out.get("sample_age_ms", 0.0))

    def _new_session(self, now: float) -> None:
        self.counts["sessions"] += 1
        if self.counts["sessions"] > 1:
            log.warning("robot road: the robot speaks again after %.0f ms of silence: a new session, answered from "
                        "zero correction", 1000.0 * (now - self._last_t))
        self._session_t = now
        self._last_stamp = self._last_late = None
        self.answerer.restart()

    def _check_limits(self, q: list[float]) -> None:
        for j, (v, (lo, hi)) in enumerate(zip(q, self.settings.limits_deg)):
            if not lo <= v <= hi:
                raise PacketError("joints", f"joint {j + 1} = {v:.3f} deg is outside the robot's limits [{lo:g}, {hi:g}]")

    def _missed(self, p) -> int:
        """How many answers the robot says it did not take since its last packet (RSI's ``Delay`` rose)."""
        return max(p.late - self._last_late, 0) if p.late is not None and self._last_late is not None else 0

    def _note_counts(self, p) -> None:
        late = gaps = 0
        if p.late is not None:
            if self._last_late is not None and p.late > self._last_late:
                late = p.late - self._last_late
            self._last_late = p.late
        step = self.answerer.stamp_step
        if self._last_stamp is not None and p.stamp - self._last_stamp > step:
            gaps = (p.stamp - self._last_stamp) // step - 1
        self._late("late_reported", "reported", late)
        self._late("stamp_gaps", "stamp_gap", gaps)

    def _late(self, key: str, kind: str, n: int) -> None:
        if n > 0:
            self.counts[key] += n
            if self.metrics is not None:
                self.metrics.count_robot_late(kind, n)

    def _write_inputs(self, p, q: list[float], now: float, out: dict) -> None:
        values = dict(zip(self._q_names, q))
        s = self.settings
        if s.owns_commands:
            self.heartbeat = (self.heartbeat + 1) & 0xFFFF
            command = p.command if p.command is not None else (_ENABLE if s.enable_on_start else 0)
            held = now - self._session_t < RESET_HOLD_S
            if held and (now == self._session_t or int(out.get("fault_word", 0)) != 0):
                command |= _RESET
            values["command_word"] = command & 0xFFFF
            values["plc_heartbeat"] = p.heartbeat if p.heartbeat is not None else self.heartbeat
        if p.payload is not None and "payload_index" in self._in:
            values["payload_index"] = p.payload
        self.image.write_values(values)

    def _drop(self, reason: str) -> None:
        """Count a dropped packet under ``reason`` (the stats and the metrics)."""
        d = self.counts["dropped"]
        d[reason] = d.get(reason, 0) + 1
        if self.metrics is not None:
            self.metrics.count_refused("robot", reason)

    def sent(self, t_in_ns: int, t_out_ns: int) -> None:
        """One answer's time from the datagram's arrival in the loop to its send (the latency's ring)."""
        us = (t_out_ns - t_in_ns) / 1000.0
        self.latency_us[self._n_latency % LATENCY_RING] = us
        self._n_latency += 1
        if t_out_ns - t_in_ns > self._slow_ns:
            self._late("slow_answers", "slow", 1)
        if self.metrics is not None:
            self.metrics.observe_robot_answer(us)
            self.metrics.count_request("robot", self.settings.robot.interface)

    def stats(self) -> dict:
        """The counts and the answers' latency (p50, p99, max in us over the last `LATENCY_RING` answers)."""
        n = min(self._n_latency, LATENCY_RING)
        lat = self.latency_us[:n]
        pct = (lambda q: round(float(np.percentile(lat, q)), 1)) if n else (lambda q: None)
        return {"interface": self.settings.robot.interface, **self.counts, "dropped": dict(self.counts["dropped"]),
                "latency_us": {"p50": pct(50), "p99": pct(99), "max": round(float(lat.max()), 1) if n else None,
                               "n": n}}


class _Datagrams(asyncio.DatagramProtocol):
    def __init__(self, road: RobotRoad):
        self.road = road
        self.transport = None

    def connection_made(self, transport) -> None:
        self.transport = transport

    def datagram_received(self, data: bytes, addr) -> None:
        t_in = time.perf_counter_ns()
        try:
            reply = self.road.received(data, addr)
        except Exception as e:  # noqa: BLE001 - one bad packet must not end the road; counted as dropped
            log.error("robot road: a packet from %s failed: %r", addr[0], e)
            self.road._drop("failed")
            return
        if reply is not None:
            self.transport.sendto(reply, addr)
            self.road.sent(t_in, time.perf_counter_ns())

    def error_received(self, exc: Exception) -> None:      # e.g. ICMP port unreachable after a send
        self.road.errors.report("robot", "send failed", repr(exc))
