"""The band a HIL run's end-to-end delay must fall in, from the loop's own parts: a run whose timing was off (a
device process the host ran late, a log stamped at the wrong time) says so instead of reporting a delay outside
the band in silence.

The delay from the force at the tool to the correction the device applied (`hil.report.end_to_end_delay`) is
at least what the causal filters in the loop hold back: the virtual sensor's low-pass (``sensor.lowpass_hz``,
2nd-order Butterworth at ``sensor.rate_hz``) and the service's (``filter``, at the cycle's rate), each its
group delay at the force's low frequencies, plus the PLC's ``plc.extra_delay_ms``. No timing can beat that:
a delay below it means the run's clocks or its log are wrong. Above it come the sample-and-hold of the
service's cycle and of the device, each at most one period (the robot's interface cycle on the robot road;
the PLC's ``plc.period_ms`` twice: its program takes a request's answer at the call after the one that sent it,
as Beckhoff's request blocks end, then holds it for a cycle), and the transport (CAN over UDP, Modbus or the robot's UDP: well under a
millisecond on one host); `SLACK_MS` covers that and a scheduler's wake-up. On the shipped scenario (a 2 ms PLC):
6.5 to 13.5 ms, against 9.94 ms in lock step and 9.03 ms in real time.
"""

from __future__ import annotations

import numpy as np
from scipy import signal

from robot_road.settings import RobotSettings
from service.filters import FilterConfig, SosLowPass
from service.task import CycleConfig
from stiffness.files.yaml_schema import deep_update, read_yaml

from .scenario import Scenario

SLACK_MS = 2.0           # transport and wake-up above the periods: generous, the band is for gross errors
FORCE_HZ = 1.0           # where the filters' group delay is read: the force's content is a few hertz
RAN_SHARE = 0.8          # a device that ran fewer of its cycles than this share was starved by the host


def group_delay_ms(sos: np.ndarray, rate_hz: float, at_hz: float = FORCE_HZ) -> float:
    """The group delay of the low-pass ``sos`` (sampled at ``rate_hz``) at ``at_hz``, ms."""
    b, a = signal.sos2tf(sos)
    _, gd = signal.group_delay((b, a), w=[at_hz], fs=rate_hz)
    return 1000.0 * float(gd[0]) / rate_hz


def delay_band_ms(scenario: Scenario, overrides: dict | None = None,
                  robot_interface: str | None = None) -> tuple[float, float]:
    """(lowest, highest) end-to-end delay (ms) the loop of ``scenario`` can show, its service config with
    ``overrides``; ``robot_interface``: the robot road's device instead of the PLC (module docstring)."""
    data = deep_update(read_yaml(scenario.resolve(scenario.service)), overrides or {})
    cycle = CycleConfig.model_validate(data.get("cycle") or {})
    rate_hz = 1000.0 / cycle.period_ms
    service = SosLowPass.from_config(FilterConfig.model_validate(data.get("filter") or {}), cycle.period_ms / 1000.0)
    s = scenario.sensor
    sensor = group_delay_ms(signal.butter(2, s.lowpass_hz, fs=s.rate_hz, output="sos"), s.rate_hz) \
        if s.lowpass_hz > 0 else 0.0
    low = sensor + group_delay_ms(service.sos, rate_hz) + scenario.plc.extra_delay_ms
    if robot_interface is None:         # the program takes a request's answer at the call after it started it
        device_ms = 2 * scenario.plc.period_ms
    else:
        device_ms = float(RobotSettings.model_validate({"interface": robot_interface}).cycle_ms)
    return low, low + cycle.period_ms + device_ms + SLACK_MS


def device_lateness(t: np.ndarray, t_end: float, period_ms: float, device: str) -> str | None:
    """The cause when the virtual ``device`` (the PLC, the robot) ran fewer than `RAN_SHARE` of the cycles its
    ``period_ms`` owes the cut (program time 0 to ``t_end``, s; ``t``: each cycle's time, its log's): a host too
    busy for it, whose log then has too few samples to tell the delay by. None when it kept up."""
    t = np.asarray(t)
    t = t[(t >= 0.0) & (t <= t_end)]
    owed = 1000.0 * t_end / period_ms
    if len(t) >= RAN_SHARE * owed:
        return None
    apart = f", {1000.0 * float(np.median(np.diff(t))):.1f} ms apart (median)" if len(t) > 1 else ""
    return (f"the virtual {device} ran {len(t)} of the {owed:.0f} cycles of {period_ms:g} ms the cut owes it{apart}: "
            "the host was too busy for it")


def delay_verdict(delay_ms: float | None, band: tuple[float, float], cause: str | None = None) -> str | None:
    """None when ``delay_ms`` is in ``band`` (or was not measured), else the sentence that says the run's
    timing was off, with its ``cause`` where known (`device_lateness`)."""
    if delay_ms is None or band[0] <= delay_ms <= band[1]:
        return None
    side = "below what the loop's filters alone hold back" if delay_ms < band[0] else "above what its periods allow"
    why = f": {cause}, so the delay cannot be told and its figures do not show the service" if cause else (
        " or its log was off, so its figures do not show the service")
    return (f"the end-to-end delay {delay_ms:.2f} ms is {side} ({band[0]:.1f} to {band[1]:.1f} ms, "
            f"hil/delay_band.py): this run's timing{why}; run it again" + (" on a quieter host" if cause else ""))


def timing_with_delays(timing: dict, delays_ms: list[float | None], band: tuple[float, float],
                       cause: str | None = None) -> dict:
    """A run's ``timing`` verdict (`hil.circle.timing_verdict`), made untrustworthy by the first of its cuts'
    delays (ms: the first cut's, then each repeat's) outside ``band``, naming that cut when there are several
    and the ``cause`` where known."""
    for k, d in enumerate(delays_ms, 1):
        off = delay_verdict(d, band, cause)
        if off is not None:
            which = f"cut {k} of {len(delays_ms)}: " if len(delays_ms) > 1 else ""
            return {**timing, "trustworthy": False, "verdict": which + off}
    return timing
