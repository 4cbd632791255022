"""The virtual F/T sensor of a HIL run, in its own process, on python-can (udp_multicast between
processes, virtual within one).

Like a Net F/T, it samples its gauges on its own clock (``rate_hz``) through its own selectable
low-pass (``lowpass_hz``, 2nd-order Butterworth; 0 = none) and answers each ATI short-data request
with the newest sample plus seeded Gaussian noise. Its clock does not depend on when requests come,
so a host that requests irregularly does not alias the 400 Hz tooth passing into the band the
compensation uses. The gauge signal is `World.sensor_wrench`, computed once for the whole pass. Fault modes for the fault-injection tests (``fault`` = (kind, t)):

stop     from t on it answers nothing (a cut cable): the service's sensor_timeout
babble   from t on it answers with garbage: an 8-byte frame cut to 5 bytes, an undefined id in
         its block and random bytes (a failing transceiver): the service's can_frame fault
"""

from __future__ import annotations

import can
import numpy as np
from scipy import signal

from hil.virtual_sensor import VirtualAtiSensor
from service.ati import BLOCK, AtiProtocol

from .priority import below_the_service
from .world import World


def serve_until(sensor: VirtualAtiSensor, ready, stop) -> None:
    """A process entry's life: start the sensor, say ready, answer until ``stop`` is set, stop it (below
    the service's priority, `hil.priority`)."""
    below_the_service()
    sensor.start()
    ready.set()
    try:
        while not stop.wait(0.05):
            pass
    finally:
        sensor.stop()


def gauge_samples(world: World, rate_hz: float, lowpass_hz: float) -> tuple[float, np.ndarray]:
    """What the sensor's gauges read on its own clock, through its own low-pass: (the time of the first
    sample, s since the cut started; the samples (N, 6)), for the whole pass and 5 s beyond."""
    t0 = world.t_start - 0.5
    grid = t0 + np.arange(int((world.t_end + 5.0 - t0) * rate_hz)) / rate_hz
    w = world.sensor_wrench(grid)
    if lowpass_hz > 0:
        sos = signal.butter(2, lowpass_hz, fs=rate_hz, output="sos")
        w = signal.sosfilt(sos, w, axis=0, zi=signal.sosfilt_zi(sos)[:, :, None] * w[0])[0]
    return t0, w


class HilSensor(VirtualAtiSensor):
    """The virtual ATI sensor, answering with the world's wrench.

    Parameters
    ----------
    bus, protocol : as `VirtualAtiSensor`
    world : World
    go : callable () -> float or None
        The monotonic time at which the cut starts (None: not yet, the tool waits at the start).
    noise : (6,) 1-sigma noise per channel (N, Nm)
    seed : int
    fault : (kind, t) or None
    """

    def __init__(self, bus: can.BusABC, protocol: AtiProtocol, world: World, go, noise, seed: int = 0,
                 fault: tuple[str, float] | None = None, rate_hz: float = 7000.0, lowpass_hz: float = 0.0):
        super().__init__(bus, protocol, load=lambda t: np.zeros(6))
        self.world = world
        self.rate = float(rate_hz)
        self.grid_t0, self.samples = gauge_samples(world, rate_hz, lowpass_hz)
        self.go = go
        self.noise = np.asarray(noise, dtype=float)
        self.rng = np.random.default_rng(seed)
        self.junk = np.random.default_rng(seed + 1)
        self.fault = fault

    def scenario_time(self, t: float) -> float:
        """Scenario time (s since the cut started) from the sensor's own time ``t``."""
        t0 = self.go()
        return self.world.t_start if t0 is None else t + self._t0 - t0

    def answer(self, t: float) -> list[tuple[int, bytes]]:
        return self.answer_at(self.scenario_time(t))

    def answer_at(self, ts: float) -> list[tuple[int, bytes]]:
        """The frames answering a request at scenario time ``ts`` (the lock-step HIL asks so, `hil.lockstep`)."""
        if self.fault is not None and self.go() is not None and ts >= self.fault[1]:
            if self.fault[0] == "stop":
                return []
            p = self.protocol
            junk = bytes(self.junk.integers(0, 256, 8, dtype=np.uint8).tolist())
            return [(p.id_1, junk[:5]), (p.base_id + BLOCK - 1, junk), (p.id_2, junk)]
        self.counter = (self.counter + 1) & 0xFFFF
        k = min(max(int((ts - self.grid_t0) * self.rate), 0), len(self.samples) - 1)
        w = self.samples[k] + self.noise * self.rng.standard_normal(6)
        return self.protocol.encode(w, 0, self.counter)


def sensor_main(scenario, robot, bus_kw: dict, ati: dict, go_value, ready, stop,
                fault: tuple[str, float] | None = None, input_map: np.ndarray | None = None) -> None:
    """Process entry: run the sensor until ``stop`` is set (multiprocessing Events and a Value).

    The sensor carries the scenario's true ``payload`` (not the service config's ``gravity``, which
    the HIL checks). ``input_map``: the truth's L (W_true = L W_measured), how the sensor is turned
    (None: aligned).
    """
    world = World(scenario, robot, scenario.payload, input_map)

    def go() -> float | None:
        v = go_value.value
        return v if v > 0 else None

    bus = can.Bus(**bus_kw)
    sensor = HilSensor(bus, AtiProtocol(**ati), world, go,
                       [scenario.sensor.noise_N] * 3 + [scenario.sensor.noise_Nm] * 3, scenario.sensor.seed, fault,
                       scenario.sensor.rate_hz, scenario.sensor.lowpass_hz)
    serve_until(sensor, ready, stop)

