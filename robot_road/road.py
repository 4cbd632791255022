"""The robot road: each packet of the robot's real-time interface answered at once from the process image.

The robot is the clock. `RobotRoad.received` runs for every datagram, in the I/O process's loop:

1. a packet from an address other than ``robot.peer`` changes nothing (counted, logged once per address);
2. the interface (`robot_road.interface`, found by ``robot.interface``) reads the packet; a malformed one, a
   stamp (the packet's sequence number or clock) repeated or a little out of order, or programmed joints that
   are not finite or outside the robot's limits are counted under their reason and dropped, unanswered;
3. a stamp that fell back far (the robot's program started the interface again), or the first packet after a
   silence of ``faults.plc_heartbeat_timeout_ms``, begins a new session (`session.Phase`): the robot holds no
   correction, and the answers ramp in from zero over ``limits.fault_ramp_s``;
4. the commanded joints, programmed plus the correction the robot holds once it takes this packet's answer, go
   into the image's ``q1..q6``, as a PLC reports its joints: the cycle computes at them and the trace records
   them. With ``plc.role: none`` the
   road also writes the command word (the robot's own element; without one, enable as ``plc.enable_on_start``
   says) and steps ``plc_heartbeat``;
5. the answer is the newest correction the cycle published, never waiting for the cycle.

A robot without a command element cannot acknowledge anything. At its first contact since the service started the
road raises the reset bit for it, as a PLC starting up does (what latched before anyone was there, e.g. a sensor
that came up late, is cleared if its cause is gone); after a later silence or restart only while the latched
fault is its own silence's (``plc_heartbeat``): any other stays, is logged, and waits for the robot's own reset
bit or a restart of the service.
"""

from __future__ import annotations

import asyncio
import logging
import time
from dataclasses import dataclass, field

import numpy as np

from io_base.errors import PlcError
from io_base.ratelog import RateLimitedLog
from io_base.recovery import RecoveryReset
from plc_link.contract import Command, Fault

from .interface import ZERO6, interface_for
from .packets import PacketError
from .session import Phase, Sessions
from .settings import RobotSettings
from .stats import LATENCY_RING, RoadCounts, RoadStats

log = logging.getLogger("stiffcomp.robot")

CYCLE_CHECK_PACKETS = 16        # packets after which the robot's own cycle is compared with cycle_ms
_ENABLE = int(Command.ENABLE)


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

    def warnings(self) -> list[str]:
        """What the road says at start about its settings (each one line)."""
        r = self.robot
        out = [w for w in (r.exposure_warning(), r.defaults_warning()) if w]
        element = r.command_element
        if self.owns_commands and element and self.enable_on_start:
            out.append(f"plc.enable_on_start: true is ignored: the robot's command element <{element}> "
                       f"(robot.{r.interface}.command_element) switches the correction, its bit 0 the enable")
        return out


class RobotRoad:
    """The robot interface as a part of the I/O server (`io_process.server.IoServer`).

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
        self.iface = interface_for(r, settings.robot_file)
        self.transport = None
        self.errors = RateLimitedLog(log, 10.0)
        self.counts = RoadCounts()
        self.sessions = Sessions(settings.silence_s, settings.ramp_s)
        self.latency_us = np.zeros(LATENCY_RING)
        self._n_latency = 0
        self.heartbeat = 0
        self._strangers: set[str] = set()
        self._to_check = None                       # the packet just answered, for the interface's checks
        self.cycle_seen: float | None = None        # the robot's cycle as its stamps say, in stamp units
        self._step = self.iface.stamp_step
        self._slow_ns = r.cycle_ms * 1_000_000
        self._q_names = [f"q{i}" for i in range(1, 7)]
        has_element = r.command_element is not None
        # the robot's first contact since the start resets what was latched before anyone was there (a sensor
        # that came up late), as a PLC's start-up does; a later session only the fault of the robot's silence
        self._first_reset = RecoveryReset(clears=0 if has_element else 0xFFFF)
        self._later_reset = RecoveryReset(clears=0 if has_element else int(Fault.PLC_HEARTBEAT))
        self.reset = self._first_reset

    # -- life cycle -------------------------------------------------------------------------------
    async def start(self) -> None:
        r = self.settings.robot
        for warning in self.settings.warnings():
            log.warning(warning)
        loop = asyncio.get_running_loop()
        try:
            self.transport, _ = await loop.create_datagram_endpoint(lambda: _Datagrams(self),
                                                                    local_addr=(r.host, r.port))
        except OSError as e:
            from io_base.listen import explain

            raise PlcError(f"cannot listen for the robot on {r.host}:{r.port}: "
                           f"{explain(e, r.host, r.port, 'robot.port', 'udp')}") from e
        log.info("robot road: %s%s", r.served(), f", packets from {r.peer} only" if r.peer else "")

    async def stop(self) -> None:
        if self.transport is not None:
            self.transport.close()
            self.transport = None
        self.errors.flush()

    @property
    def session(self):
        """The current session (`session.Session`)."""
        return self.sessions.current

    @property
    def clients(self) -> int:
        return int(self.sessions.phase(self.clock()) in (Phase.RAMPING, Phase.ANSWERING))

    # -- one datagram -------------------------------------------------------------------------------
    def received(self, data: bytes, addr) -> bytes | None:
        """The answer to one datagram from ``addr``, or None (dropped: counted, and logged at a limited rate)."""
        self.counts.packets += 1
        peer = str(addr[0])
        if not self.settings.robot.takes(peer):
            if peer not in self._strangers and len(self._strangers) < 256:
                self._strangers.add(peer)
                log.warning("robot road: a packet from %s, not robot.peer %s: dropped (further ones are only counted)",
                            peer, self.settings.robot.peer)
            self._drop("peer")
            return None
        now = self.clock()
        sessions = self.sessions
        heard, sessions.heard_t = sessions.heard_t, now
        iface = self.iface
        try:
            p = iface.parse(data)
            silent = sessions.phase(now) in (Phase.AWAITING, Phase.SILENT)
            last = self.session.stamp
            restarted = not silent and last is not None and p.stamp <= last and iface.restarted(p.stamp, last)
            new = silent or restarted
            if not new and p.stamp == last:
                raise PacketError("repeated", f"{iface.stamp_name} {p.stamp} repeated: the robot sent its last "
                                  "packet again (it did not take the answer, or the network doubled it)")
            if not new and p.stamp < last:
                raise PacketError("stamp", f"{iface.stamp_name} {p.stamp} is below the last one taken ({last}): "
                                  "a packet out of order")
            missed = 0 if new else self._missed(p)
            held = ZERO6 if new else iface.held_before(missed)
            q = iface.programmed(p, held, new)
            self._check_limits(q)
        except PacketError as e:
            self.errors.report(peer, e.reason, str(e))
            self._drop(e.reason)
            return None
        if new:                             # only a packet taken begins a session
            self._new_session(now, p.stamp, heard, restarted)
        elif missed:
            iface.missed(missed)
        self._note_counts(p)
        sessions.last_t, self.session.stamp = now, p.stamp
        self._to_check = p
        out = self.image.outputs()
        ramp = sessions.ramp(now)
        correction = [ramp * out[f"correction_q{i}"] for i in range(1, 7)]
        reply = iface.answer(p, q, correction, out["sample_age_ms"])
        # the commanded joints from this packet on: programmed plus the correction the robot takes with this answer
        self._write_inputs(p, [a + b for a, b in zip(q, iface.held)], now, out)
        self.counts.answered += 1
        return reply

    def after_answer(self) -> None:
        """What waits until the answer is sent: the interface's checks of the packet just answered (tens of us,
        kept off the answer's latency)."""
        p, self._to_check = self._to_check, None
        contradicted = None if p is None else self.iface.evidence(p)
        if contradicted:
            key, warning = contradicted
            log.warning("robot road: %s", warning)
            if self.metrics is not None:
                self.metrics.count_robot_contradiction(key)

    def _new_session(self, now: float, stamp: int, heard: float | None, restarted: bool) -> None:
        sessions = self.sessions
        if restarted:
            log.warning("robot road: the robot's %s fell back from %d to %d: its program started the interface "
                        "again; a new session, answered from zero correction", self.iface.stamp_name,
                        self.session.stamp, stamp)
        elif sessions.count > 0:
            quiet_ms = 1000.0 * (now - sessions.last_t)
            if heard is not None and heard > sessions.last_t:
                log.warning("robot road: the robot's packets were all dropped for %.0f ms (see the counts by "
                            "reason): a new session, answered from zero correction", quiet_ms)
            else:
                log.warning("robot road: the robot speaks again after %.0f ms of silence: a new session, answered "
                            "from zero correction", quiet_ms)
        sessions.begin(now, restarted)
        self.iface.restart()
        self.reset = self._first_reset if sessions.count == 1 else self._later_reset
        self.reset.recovered(now)

    def _check_limits(self, q: list[float]) -> None:
        for j, (v, (lo, hi)) in enumerate(zip(q, self.settings.limits_deg)):
            if not lo <= v <= hi:
                raise PacketError("joints", f"joint {j + 1} = {v:.3f} deg is outside the robot's limits [{lo:g}, {hi:g}]")

    def _missed(self, p) -> int:
        """How many answers the robot says it did not take since its last packet (its count of late answers rose)."""
        return max(p.late - self.session.late, 0) if p.late is not None and self.session.late is not None else 0

    def _note_counts(self, p) -> None:
        late = gaps = 0
        if p.late is not None:
            if self.session.late is not None and p.late > self.session.late:
                late = p.late - self.session.late
            self.session.late = p.late
        if self.session.stamp is not None:
            step = p.stamp - self.session.stamp
            if len(self.session.steps) < CYCLE_CHECK_PACKETS:
                self.session.steps.append(step)             # gaps counted once the robot's own step is known
                if len(self.session.steps) == CYCLE_CHECK_PACKETS:
                    self._cycle_check()
                    gaps = sum(max(d // self._step - 1, 0) for d in self.session.steps)
            elif step > self._step:
                gaps = step // self._step - 1
        self._late("late_reported", "reported", late)
        self._late("stamp_gaps", "stamp_gap", gaps)

    def _cycle_check(self) -> None:
        """The session's first steps of the stamp, against the configured cycle: a robot whose stamps rise by a
        whole multiple of it (a 12 ms IPO against cycle_ms 4) is named once, and its gaps counted on its own
        step."""
        # a robot on the configured cycle sends some packets one step apart however loaded the link; one on a
        # longer cycle never does
        seen = min(self.session.steps)
        self.cycle_seen = seen
        want = self.iface.stamp_step
        if seen > want and seen % want == 0:
            self._step = seen
            r = self.settings.robot
            unit = self.iface.stamp_unit
            log.warning("robot road: the robot's %s rises by %d %s per packet, the %s cycle_ms (%d) says %d: its "
                        "cycle looks like %d ms; set robot.%s.cycle_ms to match the robot (its gaps are counted on "
                        "the robot's own step meanwhile)", self.iface.stamp_name, seen, unit, r.interface,
                        r.cycle_ms, want, seen * r.cycle_ms // want, r.interface)

    def _reset_advice(self) -> str:
        """What resets a latched fault for a robot that sends no command word: its own reset bit, where its
        interface can carry one, or a restart of the service."""
        r = self.settings.robot
        if "command_element" in type(r.section).model_fields:
            return f"the robot's own reset bit (robot.{r.interface}.command_element, bit 2) or a restart"
        return "a restart of the service"

    def _late(self, key: str, kind: str, n: int) -> None:
        if n > 0:
            setattr(self.counts, key, getattr(self.counts, key) + n)
            if self.metrics is not None:
                self.metrics.count_robot_late(kind, n)

    def _write_inputs(self, p, q: list[float], now: float, out: dict) -> None:
        values = dict(zip(self._q_names, q))
        s = self.settings
        if s.owns_commands:
            self.heartbeat = (self.heartbeat + 1) & 0xFFFF
            fault_word = int(out["fault_word"])
            if p.command is not None:
                command = p.command                # the robot's own: its enable, tare and reset
            else:
                command = _ENABLE if s.enable_on_start else 0
                if self.reset.bit(now, fault_word):
                    command |= int(Command.RESET)
                elif fault_word and now - self.session.began <= self.reset.hold_s and not self.session.said_kept_faults:
                    self.session.said_kept_faults = True
                    log.warning("robot road: the robot is back, but fault_word 0x%04X holds faults beyond its "
                                "silence; they stay latched (the correction off) until %s", fault_word,
                                self._reset_advice())
            values["command_word"] = command & 0xFFFF
            values["plc_heartbeat"] = p.heartbeat if p.heartbeat is not None else self.heartbeat
        if p.payload is not None and "payload_index" in self.image.in_codec.index:
            values["payload_index"] = p.payload
        self.image.write_values(values)

    def _drop(self, reason: str) -> None:
        """Count a dropped packet under ``reason`` (the stats and the metrics)."""
        d = self.counts.dropped
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

    def report(self) -> RoadStats:
        """The counts, the sessions, the interface's checks and the answers' latency."""
        n = min(self._n_latency, LATENCY_RING)
        lat = self.latency_us[:n]
        pct = (lambda q: round(float(np.percentile(lat, q)), 1)) if n else (lambda q: None)
        seen = None if self.cycle_seen is None else self.cycle_seen * self.settings.robot.cycle_ms / self.iface.stamp_step
        latency = {"p50": pct(50), "p99": pct(99), "max": round(float(lat.max()), 1) if n else None, "n": n}
        return RoadStats(self.settings.robot.interface, self.counts, self.sessions.count, self.sessions.restarts,
                         self.sessions.phase(self.clock()), seen, self.iface.check_stats(), latency)

    def stats(self) -> dict:
        """`report` as the I/O server's statistics carry it out of the process."""
        return self.report().as_dict()


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
            self.road.errors.report(str(addr[0]), "failed", f"a packet could not be answered: {e!r}")
            self.road._drop("failed")
            return
        if reply is not None:
            self.transport.sendto(reply, addr)
            self.road.sent(t_in, time.perf_counter_ns())
            self.road.after_answer()

    def error_received(self, exc: Exception) -> None:      # e.g. ICMP port unreachable after a send
        self.road.errors.report("robot", "send failed", repr(exc))
