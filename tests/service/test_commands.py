"""The PLC's commands: a word with undefined bits is a fault and is not acted on; a tare under load is
refused with a status bit and a log line (issue 17, item 6)."""

from __future__ import annotations

import logging

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from test_faults import Driver, build

from plc_link.contract import COMMAND_BITS, Command, Fault, Status
from service.faults import FaultMonitor
from service.supervision import Supervisor

LIMITS = np.array([[-180.0, 180.0]] * 6)
Q = [10.0, -80.0, 100.0, 20.0, 40.0, 30.0]


def supervisor() -> Supervisor:
    return Supervisor(FaultMonitor(), LIMITS, heartbeat_timeout_s=0.0, overrun_trip_count=10)


@settings(max_examples=300, deadline=None)
@given(word=st.integers(0, 0xFFFF).filter(lambda w: w & ~COMMAND_BITS), before=st.integers(0, COMMAND_BITS),
       after=st.integers(0, COMMAND_BITS))
def test_a_word_with_undefined_bits_trips_and_is_not_acted_on(word, before, after):
    """Any undefined bit: command_invalid and no action; the valid word after it makes an edge only of a bit
    the bad word had clear (0xFFFF, then 0x0007, tares nothing)."""
    sv = supervisor()
    sv.update(0.0, before, 0, Q, False, [])
    s = sv.update(0.001, word, 1, Q, False, [])
    assert sv.faults.word & Fault.COMMAND_INVALID
    assert not (s.enabled or s.tare or s.reset)
    s = sv.update(0.002, after, 2, Q, False, [])
    assert s.tare == bool(after & ~word & Command.TARE)
    assert s.reset == bool(after & ~word & Command.RESET)
    assert bool(sv.faults.word & Fault.COMMAND_INVALID) != s.reset      # latched until a reset edge


def test_0xffff_under_load_neither_tares_nor_keeps_correcting(tmp_path, caplog):
    _, comp, src = build(tmp_path)
    drv = Driver(comp, src)
    drv.run(300)
    bias = comp.compensator.gravity.bias
    with caplog.at_level(logging.ERROR, logger="stiffcomp.faults"):
        out = drv.run(300, command=0xFFFF)
    assert comp.tares == 0 and np.array_equal(comp.compensator.gravity.bias, bias)
    assert np.all(out[-1] == 0.0) and comp.status_word & Status.FAULTED
    line = next(r.getMessage() for r in caplog.records if "command_invalid" in r.getMessage())
    assert "0xFFFF" in line and "3, 4" in line and "15" in line


def test_a_tare_under_load_is_refused_with_a_status_bit_and_a_log_line(tmp_path, caplog):
    """LOAD is 539 N (above the default tare.max_force_N = 200): refused; at 50 N it is done."""
    _, comp, src = build(tmp_path)
    drv = Driver(comp, src)
    drv.run(300)
    bias = comp.compensator.gravity.bias
    with caplog.at_level(logging.WARNING, logger="stiffcomp.service"):
        drv.run(1, command=Command.ENABLE | Command.TARE)
        drv.run(5)
    assert comp.tares == 0 and np.array_equal(comp.compensator.gravity.bias, bias)
    assert comp.status_word & Status.TARE_REFUSED and comp.status_word & Status.ACTIVE
    assert comp.signals().status_word & Status.TARE_REFUSED
    assert any("tare refused" in r.getMessage() and "tare.max_force_N = 200" in r.getMessage()
               for r in caplog.records)
    drv.run(1, command=Command.ENABLE | Command.RESET)       # a reset clears the refusal
    assert not comp.status_word & Status.TARE_REFUSED


def test_a_tare_below_the_bound_is_done_and_clears_the_refusal(tmp_path):
    light = np.tile([30.0, -20.0, 35.0, 1.0, 1.0, 0.5], (2000, 1))
    _, comp, src = build(tmp_path, wrench=light, overrides={"tare": {"max_force_N": 60.0}})
    drv = Driver(comp, src)
    drv.run(300)
    comp.compensator.tare_refused = True                     # a refusal before, e.g. under load
    drv.run(1, command=Command.ENABLE | Command.TARE)
    drv.run(2)
    assert comp.tares == 1 and not comp.status_word & Status.TARE_REFUSED
    np.testing.assert_allclose(comp.wrench_sensor, 0.0, atol=1e-9)
