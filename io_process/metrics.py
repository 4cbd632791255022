"""Prometheus metrics of the running service, for the I/O process's `/metrics` endpoint.

`ServiceMetrics` owns its own `CollectorRegistry` (never the process-wide default, so two services or
two tests never share counters) and turns what the I/O process sees into metrics:

- the cycle: count, exceeded cycles, exec time and period jitter as histograms (µs buckets around a
  1 ms period);
- faults: trips by kind (counter) and the current fault word (gauge);
- the sensor: sample rate and age of the newest sample;
- the PLC side: Modbus and ADS clients connected, requests by Modbus function (FC4 ...) and ADS
  command (Read, ReadWrite ...), refused requests by reason (Modbus exception, ADS error code, a write
  from a client that may not write), connections refused before their first request (a failed TLS
  handshake);
- the six joint corrections and the wrench (gauges).

Pure: no sockets, no threads, no clock. The I/O process feeds it and serves `render()`.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence

from prometheus_client import CollectorRegistry, Counter, Gauge, Histogram, generate_latest

from plc_link.contract import FAULT_BITS

#: µs bucket bounds for exec time and jitter: fine below the 1 ms period, coarse above it
EXEC_BUCKETS_US = (25, 50, 75, 100, 150, 200, 300, 400, 500, 600, 700, 800, 900, 1000, 1500, 2000,
                   5000, 10000)
ANSWER_BUCKETS_US = (10, 25, 50, 100, 200, 300, 500, 750, 1000, 2000, 4000, 12000)
JITTER_BUCKETS_US = (5, 10, 25, 50, 100, 200, 300, 500, 750, 1000, 2000, 5000, 10000)
JOINTS = tuple(f"q{i}" for i in range(1, 7))
WRENCH = ("fx", "fy", "fz", "mx", "my", "mz")
PROTOCOLS = ("modbus", "ads")     # modbus_tls (Modbus/TCP Security) shows once it serves
CONTENT_TYPE = "text/plain; version=0.0.4; charset=utf-8"


class ServiceMetrics:
    """The service's metrics in a registry of their own.

    Parameters
    ----------
    fault_bits : mapping of fault kind -> bit of the fault word, optional
        By default the contract's `FAULT_BITS`; every bit that rises in the
        ``fault_word`` handed to `update_values` counts one fault of its kind, and every kind is shown
        from the start with a count of 0. `count_fault` counts a fault explicitly either way.
    protocols : the PLC protocols whose clients are counted (shown with 0 from the start)

    Notes
    -----
    ``cycle_count`` and ``exceed_count`` arrive as the absolute values of the registers; the counters
    follow them by their increase. A value that falls (the cycle process restarted) is taken as a
    restart from zero, as Prometheus' ``rate()`` treats a counter reset.
    """

    def __init__(self, fault_bits: Mapping[str, int] | None = None, protocols: Iterable[str] = PROTOCOLS):
        self.registry = r = CollectorRegistry(auto_describe=True)
        self._fault_bits = dict(FAULT_BITS if fault_bits is None else fault_bits)
        self._last: dict[str, float] = {}
        self._fault_word = 0
        p = "stiffcomp_"
        self.cycles = Counter(p + "cycles", "cycles run by the 1 ms task", registry=r)
        self.exceeded = Counter(p + "cycles_exceeded", "cycles whose work overran the period, "
                                "and deadlines skipped after an overrun", registry=r)
        self.exec_us = Histogram(p + "cycle_exec_microseconds", "work time of a cycle, us",
                                 buckets=EXEC_BUCKETS_US, registry=r)
        self.jitter_us = Histogram(p + "cycle_jitter_microseconds", "|actual - nominal period| of a cycle, us",
                                   buckets=JITTER_BUCKETS_US, registry=r)
        self.faults = Counter(p + "faults", "faults tripped, by kind", ["kind"], registry=r)
        self.fault_word = Gauge(p + "fault_word", "the latched fault word (docs/register_map.md)", registry=r)
        self.status_word = Gauge(p + "status_word", "the status word (docs/register_map.md)", registry=r)
        self.task_state = Gauge(p + "task_state", "0 init, 1 run, 2 stop (as TwinCAT's task state)", registry=r)
        self.sensor_rate = Gauge(p + "sensor_sample_rate_hertz", "F/T samples received per second", registry=r)
        self.sensor_age = Gauge(p + "sensor_sample_age_seconds", "age of the newest F/T sample", registry=r)
        self.clients = Gauge(p + "clients_connected", "PLC clients connected, by protocol", ["protocol"],
                             registry=r)
        self.requests = Counter(p + "requests", "PLC requests served, by protocol and function",
                                ["protocol", "function"], registry=r)
        self.refused = Counter(p + "requests_refused", "PLC requests refused, by protocol and reason",
                               ["protocol", "reason"], registry=r)
        self.connections_refused = Counter(p + "connections_refused", "PLC connections closed before their "
                                           "first request, by protocol and reason (TLS handshake refused)",
                                           ["protocol", "reason"], registry=r)
        self.correction = Gauge(p + "correction_degrees", "joint correction sent to the PLC, deg", ["joint"],
                                registry=r)
        self.force = Gauge(p + "wrench_force_newtons", "filtered, gravity-compensated force, N, base axes",
                           ["axis"], registry=r)
        self.moment = Gauge(p + "wrench_moment_newton_metres", "filtered, gravity-compensated moment, Nm",
                            ["axis"], registry=r)
        self.robot_answer_us = Histogram(p + "robot_answer_microseconds", "robot road: a packet's arrival in the "
                                         "I/O loop to its answer's send, us", buckets=ANSWER_BUCKETS_US, registry=r)
        self.robot_late = Counter(p + "robot_late_answers", "robot road: answers late or missing, by how it is "
                                  "known: reported (the robot's own count, RSI Delay), stamp_gap (robot packets "
                                  "missing, IPOC or seqno skipped), slow (an answer that took over the robot's "
                                  "cycle here)", ["kind"], registry=r)
        self.robot_contradictions = Counter(p + "robot_setting_contradicted", "robot road: the robot's packets "
                                            "contradict a setting about what they hold (the key; the log names "
                                            "the evidence)", ["key"], registry=r)
        for proto in protocols:
            self.clients.labels(proto).set(0)
        for kind in self._fault_bits:
            self.faults.labels(kind)
        self._gauges: dict[str, Gauge] = {"fault_word": self.fault_word, "status_word": self.status_word,
                                          "task_state": self.task_state}
        for j in JOINTS:
            self._gauges[f"correction_{j}"] = self.correction.labels(j)
        for a in WRENCH:
            self._gauges[f"wrench_{a}"] = (self.force if a[0] == "f" else self.moment).labels(a)

    def observe_cycles(self, exec_us: Sequence[float], jitter_us: Sequence[float] = ()) -> None:
        """Add the exec times and period jitters (µs) of cycles seen since the last call."""
        for x in exec_us:
            self.exec_us.observe(float(x))
        for x in jitter_us:
            self.jitter_us.observe(float(x))

    def update_values(self, values: Mapping[str, float]) -> None:
        """Take the service's to_plc values by register name.

        Used: ``cycle_count``, ``exceed_count`` (counters), ``fault_word`` (gauge, and fault kinds by
        rising bit when ``fault_bits`` was given), ``status_word``, ``task_state``,
        ``correction_q1..6`` and ``wrench_fx..mz`` (gauges). Other names are ignored, so the whole
        block can be passed as it is.
        """
        for name, counter in (("cycle_count", self.cycles), ("exceed_count", self.exceeded)):
            if name in values:
                self._follow(name, float(values[name]), counter)
        if "fault_word" in values:
            word = int(values["fault_word"])
            rising = word & ~self._fault_word
            for kind, bit in self._fault_bits.items():
                if rising & (1 << bit):
                    self.faults.labels(kind).inc()
            self._fault_word = word
        for name, gauge in self._gauges.items():
            if name in values:
                gauge.set(float(values[name]))

    def _follow(self, name: str, value: float, counter: Counter) -> None:
        last = self._last.get(name, 0.0)
        counter.inc(value - last if value >= last else value)
        self._last[name] = value

    def count_fault(self, kind: str) -> None:
        """One fault of ``kind`` tripped (when not derived from the fault word)."""
        self.faults.labels(kind).inc()

    def set_clients(self, protocol: str, n: int) -> None:
        """``n`` clients of ``protocol`` ("modbus", "ads") are connected now."""
        self.clients.labels(protocol).set(n)

    def count_request(self, protocol: str, function: str, n: int = 1) -> None:
        """``n`` requests of ``function`` (e.g. "read_input_registers", "Read") served."""
        self.requests.labels(protocol, function).inc(n)

    def count_refused(self, protocol: str, reason: str, n: int = 1) -> None:
        """``n`` requests refused for ``reason`` (e.g. "illegal_address", "unknown_route")."""
        self.refused.labels(protocol, reason).inc(n)

    def observe_robot_answer(self, us: float) -> None:
        """One robot packet answered ``us`` microseconds after it arrived in the I/O loop."""
        self.robot_answer_us.observe(us)

    def count_robot_late(self, kind: str, n: int = 1) -> None:
        """``n`` robot answers late or missing, known as ``kind`` (reported, stamp_gap, slow)."""
        self.robot_late.labels(kind).inc(n)

    def count_robot_contradiction(self, key: str) -> None:
        """The robot's packets contradict the setting ``key`` (e.g. joints_include_correction)."""
        self.robot_contradictions.labels(key).inc()

    def count_connection_refused(self, protocol: str, reason: str) -> None:
        """One connection refused before its first request (e.g. "no client certificate")."""
        self.connections_refused.labels(protocol, reason).inc()

    def set_sensor(self, rate_hz: float, age_s: float) -> None:
        """The F/T sample rate (Hz) and the age of the newest sample (s)."""
        self.sensor_rate.set(rate_hz)
        self.sensor_age.set(age_s)

    def render(self) -> bytes:
        """The Prometheus text exposition (serve it with ``CONTENT_TYPE``)."""
        return generate_latest(self.registry)
