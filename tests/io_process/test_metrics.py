"""The metrics render as Prometheus text that prometheus-client's own parser reads, and counters rise."""

from __future__ import annotations

from prometheus_client.parser import text_string_to_metric_families

from io_process.metrics import ServiceMetrics
from plc_link.contract import FAULT_BITS


def samples(m: ServiceMetrics) -> dict[tuple, float]:
    out = {}
    for fam in text_string_to_metric_families(m.render().decode()):
        for s in fam.samples:
            out[(s.name, tuple(sorted(s.labels.items())))] = s.value
    return out


def block(cycles: int, exceeded: int, fault_word: int = 0) -> dict[str, float]:
    v = {"cycle_count": cycles, "exceed_count": exceeded, "fault_word": fault_word, "status_word": 3,
         "task_state": 1, "last_exec_us": 120.0}
    v.update({f"correction_q{i}": 0.01 * i for i in range(1, 7)})
    v.update({f"wrench_{a}": k + 1.0 for k, a in enumerate(("fx", "fy", "fz", "mx", "my", "mz"))})
    return v


def test_counters_rise_and_gauges_follow():
    m = ServiceMetrics(fault_bits=FAULT_BITS)
    m.update_values(block(1000, 2))
    m.observe_cycles([80.0, 120.0, 1500.0], [3.0, 40.0])
    m.set_clients("modbus", 2)
    m.count_request("modbus", "read_input_registers", 5)
    m.count_refused("ads", "unknown_route")
    m.set_sensor(1000.0, 0.002)
    a = samples(m)

    m.update_values(block(3000, 5, fault_word=1 << FAULT_BITS["overrun"]))
    m.observe_cycles([90.0], [7.0])
    m.count_request("modbus", "read_input_registers")
    m.count_refused("ads", "unknown_route")
    m.count_fault("sensor_timeout")
    b = samples(m)

    assert a[("stiffcomp_cycles_total", ())] == 1000
    assert b[("stiffcomp_cycles_total", ())] == 3000
    assert b[("stiffcomp_cycles_exceeded_total", ())] > a[("stiffcomp_cycles_exceeded_total", ())]
    assert b[("stiffcomp_cycle_exec_microseconds_count", ())] == 4
    assert a[("stiffcomp_cycle_exec_microseconds_bucket", (("le", "1000.0"),))] == 2   # 1500 us overran
    assert b[("stiffcomp_cycle_jitter_microseconds_count", ())] == 3
    req = ("stiffcomp_requests_total", (("function", "read_input_registers"), ("protocol", "modbus")))
    assert (a[req], b[req]) == (5, 6)
    ref = ("stiffcomp_requests_refused_total", (("protocol", "ads"), ("reason", "unknown_route")))
    assert b[ref] > a[ref]
    assert a[("stiffcomp_faults_total", (("kind", "overrun"),))] == 0        # every kind shown from the start
    assert b[("stiffcomp_faults_total", (("kind", "overrun"),))] == 1        # from the rising fault bit
    assert b[("stiffcomp_faults_total", (("kind", "sensor_timeout"),))] == 1  # counted explicitly
    assert b[("stiffcomp_fault_word", ())] == 1 << FAULT_BITS["overrun"]
    assert a[("stiffcomp_clients_connected", (("protocol", "ads"),))] == 0
    assert a[("stiffcomp_clients_connected", (("protocol", "modbus"),))] == 2
    assert a[("stiffcomp_sensor_sample_rate_hertz", ())] == 1000
    assert a[("stiffcomp_correction_degrees", (("joint", "q6"),))] == 0.06
    assert a[("stiffcomp_wrench_moment_newton_metres", (("axis", "mz"),))] == 6.0


def test_a_latched_fault_counts_once_and_a_restart_keeps_the_counter_rising():
    m = ServiceMetrics(fault_bits=FAULT_BITS)
    bit = 1 << FAULT_BITS["sensor_timeout"]
    for _ in range(3):                               # the bit stays latched: one trip, not three
        m.update_values({"cycle_count": 500, "fault_word": bit})
    m.update_values({"cycle_count": 100, "fault_word": 0})    # the cycle process started again
    m.update_values({"cycle_count": 200, "fault_word": bit})  # and the fault trips again
    s = samples(m)
    assert s[("stiffcomp_faults_total", (("kind", "sensor_timeout"),))] == 2
    assert s[("stiffcomp_cycles_total", ())] == 500 + 100 + 100


def test_each_instance_has_its_own_registry():
    a, b = ServiceMetrics(), ServiceMetrics()
    a.update_values({"cycle_count": 7})
    assert samples(b)[("stiffcomp_cycles_total", ())] == 0


def test_every_metric_the_service_registers_is_in_deploy_md_with_its_type():
    """docs/deploy.md's table of what /metrics exports: each metric the service registers, by the name a
    scrape shows (a counter's with _total), and its type; and no row for a metric that does not exist."""
    import re
    from pathlib import Path

    registered = {f"{m.name}_total" if m.type == "counter" else m.name: m.type
                  for m in ServiceMetrics().registry.collect()}
    text = (Path(__file__).resolve().parents[2] / "docs" / "deploy.md").read_text(encoding="utf-8")
    table = text.split("What it exports", 1)[1].split("\n\n", 2)[1]
    documented = {}
    for row in table.splitlines()[2:]:
        cells = re.split(r"(?<!\\)\|", row)
        for name in re.findall(r"`(stiffcomp_\w+)`", cells[1]):
            documented[name] = cells[2].strip()
    assert documented == registered
