"""The HIL's end-to-end delay (issue 45, item 5): once in some thirty runs it read 4 ms instead of 8.

The cause: the virtual PLC stamped each cycle with its deadline, and after an overrun the catch-up rule starts
the next cycle at once on a deadline up to a period (4 ms) past, so a loaded host logged corrections read that
much later at the deadline's time, and the delay came out short by as much. Each cycle is now stamped when it
runs. And the run says when its delay is outside the band the loop's own filters and periods allow
(`hil.delay_band`); lock step and real time hold it there (test_hil_iso9283.py, test_hil_cli.py)."""

from __future__ import annotations

import numpy as np
import pytest

from hil import report
from hil.cell_network import ImageNetwork
from hil.delay_band import delay_band_ms, delay_verdict, timing_with_delays
from hil.device_log import Track
from hil.plc_program import generate_program
from hil.report import end_to_end_delay
from hil.virtual_plc import VirtualPlc
from hil.world import World
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from stiffness.model.stiffness_model import StiffnessModel
from testlib.hil import ROOT, scenario

PERIOD = 0.004


class LateClock:
    """A clock each reading of which is ``step`` s after the last: cycles that overrun their 4 ms."""

    def __init__(self, start: float, step: float):
        self.now, self.step, self.readings = start, step, []

    def __call__(self) -> float:
        self.now += self.step
        self.readings.append(self.now)
        return self.now


@pytest.fixture(scope="module")
def program(tmp_path_factory):
    return generate_program(RegisterMap.from_yaml(ROOT / "config" / "registers.yaml"), 502, 1,
                            tmp_path_factory.mktemp("plc"))


@pytest.mark.parametrize("step", [0.0013, 0.0031, 0.0047])
def test_a_late_plc_cycle_is_stamped_when_it_ran_not_at_its_deadline(program, step):
    """However late the host runs the virtual PLC, each cycle's program time is the clock's reading when it
    started (the read follows at once), never the deadline the catch-up rule started it on."""
    rmap = RegisterMap.from_yaml(ROOT / "config" / "registers.yaml")
    seen = []
    image = ProcessImage(rmap)                                  # no service publishes: the stamps are tested
    plc = VirtualPlc(program, ImageNetwork(image, rmap), rmap, lambda t: [0.0] * 6, False, PERIOD)
    cycle = plc.cycle
    plc.cycle = lambda t: (seen.append(t), cycle(t))[1]
    t0 = 100.0
    clock = LateClock(t0, step)
    try:
        log = plc.run(0.0, 0.2, t0, clock=clock)
    finally:
        image.close()
    t = log.t
    assert len(t) > 10 and np.array_equal(t, np.asarray(seen))
    assert np.all(np.isin(np.round(t + t0, 9), np.round(clock.readings, 9)))   # a reading of the clock, each
    due = t0 + np.floor(np.round(t / PERIOD, 6)) * PERIOD
    assert np.all(t + t0 >= due - 1e-9)
    if step > PERIOD / 2:                                       # overruns: deadline stamps would lag behind
        assert plc.overruns > 0 and np.max(t + t0 - due) > PERIOD / 4


def test_the_band_holds_the_measured_delay_and_flags_half_of_it():
    """The shipped scenario: the filters hold back 6.5 ms, the periods and transport allow 7 more (the PLC's
    2 ms twice: its program takes a request's answer at its next cycle); 9.94 ms (lock step) and 9.03 ms (real
    time) are inside, the 4.0 ms of issue 45 below, named as such."""
    band = delay_band_ms(scenario())
    assert 6.0 < band[0] < 7.99 and 12.0 < band[1] < 15.0
    assert delay_verdict(9.94, band) is None and delay_verdict(9.03, band) is None and delay_verdict(None, band) is None
    off = delay_verdict(4.0, band)
    assert off is not None and "4.00 ms is below what the loop's filters alone hold back" in off
    assert "above what its periods allow" in delay_verdict(band[1] + 1.0, band)


def test_the_band_follows_the_loop_it_is_given():
    """An extra PLC delay moves the band by as much; a slower service filter raises its floor."""
    sc = scenario()
    base = delay_band_ms(sc)
    sc.plc.extra_delay_ms = 8.0
    assert delay_band_ms(sc) == pytest.approx((base[0] + 8.0, base[1] + 8.0))
    slower = delay_band_ms(scenario(), {"filter": {"cutoff_hz": 50.0}})
    assert slower[0] > base[0] + 2.0                            # 2nd-order Butterworth: ~4.5 ms at 50 Hz, 2.25 at 100


def test_a_repeat_whose_delay_is_off_makes_the_run_untrustworthy_and_is_named():
    """`--repeat 3` through RSI once gave 3.95 ms: the repeats are checked, not the first cut alone."""
    band = delay_band_ms(scenario())
    calm = {"exceeded_share": 0.0, "trustworthy": True, "verdict": "the 1 ms cycle kept its deadlines"}
    assert timing_with_delays(calm, [8.0, 7.9, None], band) == calm
    t = timing_with_delays(calm, [8.0, 7.9, 3.95], band)
    assert t["trustworthy"] is False and t["verdict"].startswith("cut 3 of 3: the end-to-end delay 3.95 ms")
    assert t["exceeded_share"] == 0.0 and calm["trustworthy"] is True                 # the input left alone
    assert timing_with_delays(calm, [4.0], band)["verdict"].startswith("the end-to-end delay 4.00 ms")


RSI_12MS = ROOT / "tests" / "data" / "hil" / "rsi_12ms_cut.npz"   # the compensated cut through RSI at 12 ms,
                                                                   # one real-time run of the shipped scenario


def test_a_sparse_log_reads_the_delay_it_has_whatever_its_sampling(monkeypatch):
    """A robot that reports every 12 ms: the fit on its packets reads the chain's delay (the 4 ms road's 8.0 ms),
    and the same cut sampled every 24 or 48 ms, from either phase, reads it within the band too. Fitted on the raw force, the tooth-passing content
    aliases: it read 5.5 ms, below what the filters alone hold back."""
    sc = scenario()
    world = World(sc, StiffnessModel.from_yaml(sc.resolve(sc.truth)).robot)
    log = Track.load(RSI_12MS)
    low, _ = delay_band_ms(sc, robot_interface="kuka_rsi")
    every = [end_to_end_delay(world, Track(log.t[start::n], log.q_ref[start::n], log.q_cmd[start::n]))
             for n in (1, 2, 4) for start in {0, n // 2}]
    assert all(low <= d * 1000.0 <= 9.0 for d in every), every          # measured 6.8-8.3 ms
    monkeypatch.setattr(report, "ALIAS_MS", 1e9)                # no interval average: the tooth period's alone
    assert low <= end_to_end_delay(world, log) * 1000.0 <= 9.0
    monkeypatch.setattr(report, "TOOTH_SAMPLES", 1)             # the raw force: the reading of the issue
    assert end_to_end_delay(world, log) * 1000.0 < low


PLC_2MS = ROOT / "tests" / "data" / "hil" / "plc_2ms_cut.npz"    # a compensated cut through the 2 ms PLC program,
                                                                 # one real-time run of the shipped scenario


def _minima(cost: np.ndarray, band: tuple[float, float]) -> list[float]:
    lags = report.LAGS_S * 1000.0
    return [lags[k] for k in range(1, len(cost) - 1)
            if cost[k] < cost[k - 1] and cost[k] < cost[k + 1] and band[0] - 5 <= lags[k] <= band[1] + 5]


def test_the_tooth_passing_leaves_the_delay_fit_one_minimum_which_picks_the_raw_forces(monkeypatch):
    """Issue 50, item 15: the 400 Hz teeth sampled by a 2 ms PLC give the fit on the raw force a minimum every
    1-2.5 ms, and its lowest read 6.0 ms on a quiet host once (below the band), 8.0 or 10.0 in other runs; the
    force averaged over one tooth period leaves one minimum, in the band, and the delay is the raw force's
    lowest minimum within half a tooth period of it."""
    sc = scenario()
    world = World(sc, StiffnessModel.from_yaml(sc.resolve(sc.truth)).robot)
    log = Track.load(PLC_2MS)
    band = delay_band_ms(sc)
    tooth_s = 1.0 / world.milling.f_tooth
    averaged = (np.arange(report.TOOTH_SAMPLES) + 0.5) / report.TOOTH_SAMPLES * tooth_s - tooth_s / 2
    (one,) = _minima(report.delay_cost(world, log, averaged), band)
    raw = _minima(report.delay_cost(world, log, np.zeros(1)), band)
    assert band[0] <= one <= band[1] and len(raw) >= 3
    delay = end_to_end_delay(world, log) * 1000.0
    assert band[0] <= delay <= band[1] and abs(delay - one) <= 1000.0 * tooth_s / 2 + 0.5
    assert min(raw, key=lambda m: abs(m - delay)) == pytest.approx(delay, abs=0.5)    # a raw minimum, refined


def test_a_device_that_did_not_keep_its_cycles_is_named_as_the_cause_of_a_delay_outside_the_band():
    """Beside two busy processes the PLC at nice 5 ran 754 of the 2409 cycles a cut owes it, 4.6 ms apart, and
    its log read 2.5 ms: the verdict names the starved device, not only "the timing was off"."""
    from hil.delay_band import device_lateness

    t_end, band = 4.8, delay_band_ms(scenario())
    starved = np.arange(-0.2, t_end, 0.0046)                   # each cycle's time
    kept = np.arange(-0.2, t_end, 0.002)
    assert device_lateness(kept, t_end, 2.0, "PLC") is None
    cause = device_lateness(starved, t_end, 2.0, "PLC")
    ran = int(((starved >= 0) & (starved <= t_end)).sum())
    assert cause.startswith(f"the virtual PLC ran {ran} of the 2400 cycles of 2 ms") and "4.6 ms apart" in cause
    calm = {"exceeded_share": 0.0, "trustworthy": True, "verdict": "the 1 ms cycle kept its deadlines"}
    t = timing_with_delays(calm, [2.5], band, cause)
    assert t["trustworthy"] is False and cause in t["verdict"] and "on a quieter host" in t["verdict"]
    assert timing_with_delays(calm, [9.9], band, cause) == calm       # a delay in the band stands
