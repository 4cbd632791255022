"""The CAN -> PLC latency's machinery (`hil.latency.measure`, run by benchmarks/bench_latency.py): the virtual sensor,
the service and the virtual PLC running the cell's program, each sample's number read back out of the wrench
registers. The figures are the benchmark's (docs/benchmarks.md); this holds that the measurement runs and that
what it reports is a latency: ordered percentiles, no sample seen before it was sent, the PLC's own cycle."""

from __future__ import annotations

from hil.latency import measure
from hil.scenario import load_scenario
from stiffness.model.stiffness_model import StiffnessModel


def test_the_latency_benchmark_measures_samples_the_plc_read():
    sc = load_scenario()
    sc.plc.period_ms = 2.0
    robot = StiffnessModel.from_yaml(sc.resolve(sc.truth)).robot.source
    res = measure(sc, sc.resolve(sc.model), robot, seconds=2.0)
    assert res["samples"] >= 200, res                  # a read every 2 ms shows a new sample most times
    assert 0.0 < res["p50_ms"] <= res["p99_ms"] <= res["max_ms"] < 1000.0, res
    assert res["plc_period_ms"] == 2.0 and res["service_cycles"] > 0, res
