"""The steady cycle (`service.steady`) does what the Python glue does: two compiled services, one with steady
cycles and one without, run the same cycles (the same log, the same PLC values at the same times) through every
kind of event (enable, tare, reset, an undefined command bit, the heartbeat's changes and its timeout, moving
and invalid joints, a payload switch and an index with no set, overruns, a sample that is not finite, bad and
missing frames, a reload) and publish the same bytes to the PLC and the trace, with the same faults and state,
cycle after cycle."""

from __future__ import annotations

import math

import numpy as np
import pytest

from hil.testing import write_config
from plc_link.contract import Command
from service.app import Service
from service.ati import AtiProtocol
from service.config import load_config
from service.reload import prepare
from service.sources.replay import write_log
from service.trace import TraceOptions

N = 2400
ENABLE, TARE, RESET = int(Command.ENABLE), int(Command.TARE), int(Command.RESET)
SPINDLE = {"index": 1, "name": "spindle", "mass_kg": 18.0, "cog_mm": [5.0, 0.0, 140.0], "bias": [1.0, 0, 2.0, 0, 0.1, 0]}


def the_log(path, n: int) -> None:
    """A milling load at 700 Hz (cycles with no sample, one or two), one sample with the sensor's status bit,
    a frame of the wrong length and a foreign one."""
    k = np.arange(n)[:, None]
    w = np.hstack([300 * np.cos(0.01 * k), 300 * np.sin(0.01 * k), 150 + 0 * k, 20 * np.sin(0.01 * k),
                   20 * np.cos(0.01 * k), 1 + 0 * k])
    status = np.zeros(n, dtype=int)
    status[900] = 0x8000
    base = AtiProtocol().base_id
    write_log(path, w, rate_hz=700.0, status=status,
              extra=[(1300, base + 6, b"\x01\x02"), (1700, 0x7F0, bytes(8))])


def plc(k: int) -> dict[str, float]:
    """The PLC's values at cycle k: enabled from 50 with a tare at 400, an undefined bit at 600, a reset at
    700 and 1600; the heartbeat toggles every 4 cycles but stands still 1000-1250 (a timeout of 200 ms); the
    joints move 1800-1900, are not finite at 1950 and beyond their limits at 1960; payload set 1 from 2000,
    set 7 (none) from 2200."""
    cmd = 0 if k < 50 else ENABLE
    cmd |= TARE if 400 <= k < 405 else 0
    cmd |= 0x100 if k == 600 else 0
    cmd |= RESET if k in (700, 701, 1600, 2300) else 0
    hb = (k // 4) & 0xFFFF if not 1000 <= k < 1250 else 77
    q = [0.0, -90.0, 90.0, 0.0, 45.0, 0.0]
    if 1800 <= k < 1900:
        q = [0.01 * (k - 1800), -90.0, 90.0, 0.0, 45.0 + 0.02 * (k - 1800), 0.0]
    if k == 1950:
        q = [0.0, -90.0, 90.0, 0.0, float("nan"), 0.0]
    if k == 1960:
        q = [0.0, -90.0, 90.0, 0.0, 500.0, 0.0]
    payload = 0 if k < 2000 else (1 if k < 2200 else 7)
    return {"command_word": cmd, "plc_heartbeat": hb, **{f"q{i + 1}": v for i, v in enumerate(q)},
            "payload_index": payload}


def state(s: Service) -> tuple:
    sup, comp = s.cycle.supervisor, s.cycle.compensator
    return (s.image.outputs(), comp.faults.word, dict(comp.faults.trips), sup.prev_command, sup.prev_hb,
            sup.hb_change_t, sup.plc_seen, sup.overruns, sup._q_last, comp.t_prev, comp.samples, comp.sample_t,
            comp.tares, comp.tare_refused, comp.have_sample, comp.limiter.safe, comp.ramping, s.cycle.status_word,
            s.record, comp.payloads.active.index)


@pytest.fixture(scope="module")
def services(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("steady")
    the_log(tmp / "ft.blf", 2 * N)
    cfg = load_config(write_config(tmp, {
        "source": {"replay": {"file": str(tmp / "ft.blf"), "loop": False}},
        "plc": {"role": "none"}, "ads": {"enabled": False}, "monitoring": {"enabled": False},
        "gravity": {"payloads": [SPINDLE], "switch_ramp_s": 0.05},
        "tare": {"max_force_N": 5000.0}, "faults": {"overrun_trip_count": 3, "plc_heartbeat_timeout_ms": 200}}))
    out = [Service(cfg, TraceOptions(tmp / f"trace{k}.csv")) for k in range(2)]
    for s in out:
        s.wait_compiled()
    yield out
    for s in out:
        s.stop()


def test_steady_cycles_publish_what_the_glue_publishes(services):
    steady, glue = services
    glue._steady.export = lambda: None          # never armed: every cycle runs the glue
    runs = []
    run = steady._steady.run
    steady._steady.run = lambda t, reading: runs.append(run(t, reading)) or runs[-1]
    path = steady.cfg.path
    for k in range(N):
        t = 0.001 * k + 0.0001 * (k % 3)         # (a deadline a little late now and then)
        exceeded = k % 97 == 0 or 1500 <= k < 1504
        if k == 1100:                            # a reload: a new limiter's rate
            text = path.read_text()
            assert "max_rate_deg_s: 5.0" in text
            path.write_text(text.replace("max_rate_deg_s: 5.0", "max_rate_deg_s: 3.0"))
            for s in services:
                got = prepare(s.cfg, s.model, s.rmap, s.cycle)
                s.pending.append(got.swap)
        for s in services:
            s.image.write_values(plc(k))
            assert s.work(t, exceeded)
        a, b = state(steady), state(glue)
        assert a == b, (k, [(x, y) for x, y in zip(a, b) if x != y])
        n = steady.trace._n
        assert n == glue.trace._n and steady.trace.table[n - 1].tobytes() == glue.trace.table[n - 1].tobytes(), k
    assert sum(runs) > N / 2                     # most cycles were steady ones
    assert steady.cycle.reloads == glue.cycle.reloads == 1 and steady.cycle.compensator.limiter.rate == [3.0] * 6
    word = steady.cycle.faults.trips
    for kind in ("sensor_status", "can_frame", "command_invalid", "plc_heartbeat", "joint_limits", "value_invalid",
                 "payload_invalid", "overrun"):
        assert word[kind] >= 1, kind             # each event happened
    assert steady.cycle.compensator.tares == 1 and not math.isnan(steady.record.correction_q1)


def test_steady_cycles_allocate_nothing_that_stays(tmp_path):
    """sys.getallocatedblocks does not grow from one window of 1,500 steady cycles (`Service.work`, the trace
    on) to the next, and the steady call ran them."""
    import gc
    import sys

    k = np.arange(8000)[:, None]
    write_log(tmp_path / "ft.blf", np.hstack([300 * np.cos(0.01 * k), 300 * np.sin(0.01 * k), 150 + 0 * k,
                                              20 * np.sin(0.01 * k), 20 * np.cos(0.01 * k), 1 + 0 * k]), rate_hz=700.0)
    cfg = load_config(write_config(tmp_path, {
        "source": {"replay": {"file": str(tmp_path / "ft.blf"), "loop": False}},
        "plc": {"role": "none"}, "ads": {"enabled": False}, "monitoring": {"enabled": False},
        "faults": {"plc_heartbeat_timeout_ms": 0}}))
    s = Service(cfg, TraceOptions(tmp_path / "trace.csv"))
    try:
        s.wait_compiled()
        runs = []
        run = s._steady.run
        s._steady.run = lambda t, reading: runs.append(run(t, reading)) or runs[-1]
        s.image.write_values({**plc(100), "plc_heartbeat": 0})
        k = 0

        def cycles(n: int) -> None:
            nonlocal k
            for _ in range(n):
                assert s.work(0.001 * k, False)
                k += 1

        cycles(1000)
        gc.collect()
        gc.disable()
        grown = []
        try:
            cycles(500)
            for _window in range(2):
                before = sys.getallocatedblocks()
                cycles(1500)
                grown.append(sys.getallocatedblocks() - before)
        finally:
            gc.enable()
        assert sum(runs[-3000:]) == 3000            # every cycle of the windows was a steady one
        assert max(grown) <= 10, f"blocks that stayed per window of 1,500 cycles: {grown}"
    finally:
        s.stop()
