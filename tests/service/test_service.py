"""The assembled service: a live CAN source with the virtual sensor, and the error policy of the cycle."""

from __future__ import annotations

import can
import numpy as np
import pytest

from hil.testing import free_port, write_config
from hil.virtual_sensor import VirtualAtiSensor
from plc_link.contract import Status
from plc_link.register_map import RegisterMap  # noqa: F401  (the service imports it too)
from service.app import Service
from service.ati import AtiProtocol
from service.config import load_config
from service.sources.replay import ReplaySource
from testlib.common import wait_for

pytestmark = pytest.mark.realtime


def test_service_with_a_live_can_sensor(tmp_path):
    load = np.array([150.0, -80.0, 220.0, 6.0, 3.0, -2.0])
    cfg = load_config(write_config(tmp_path, {
        "source": {"type": "can", "can": {"interface": "virtual", "channel": "svc_can"}},
        "plc": {"role": "none", "enable_on_start": True},
        "gravity": {"tool": {"mass_kg": 0.0}, "bias": [0.0] * 6},
        "faults": {"overrun_trip_count": 1000, "sensor_timeout_ms": 200}}))
    with VirtualAtiSensor(can.Bus(interface="virtual", channel="svc_can"), AtiProtocol(), lambda t: load):
        s = Service(cfg)
        s.start()
        try:
            assert wait_for(lambda: s.cycle.status_word & 0x2 and abs(s.cycle.correction[0]) > 1e-4)
            out = s.image.outputs()
        finally:
            s.stop()
    assert out["fault_word"] == 0
    assert np.isclose(np.linalg.norm([out["wrench_fx"], out["wrench_fy"], out["wrench_fz"]]),
                      np.linalg.norm(load[:3]), rtol=1e-3)


class BrokenSource(ReplaySource):
    """A real replay backend whose read fails after a while (like a driver raising mid-run)."""

    def _frames(self, t):
        if t > 0.05:
            raise OSError("the driver went away")
        return super()._frames(t)


def test_an_unexpected_error_stops_the_cycle_with_zero_correction(tmp_path):
    cfg = load_config(write_config(tmp_path, {"plc": {"role": "none", "enable_on_start": True},
                                              "faults": {"overrun_trip_count": 1000}}))
    s = Service(cfg)
    s.source = BrokenSource(s.source.frames, pacing="realtime", loop=True, protocol=AtiProtocol(),
                            timeout_s=0.01, max_force_N=2500.0, max_torque_Nm=250.0)
    s.start()
    try:
        assert s.failed.wait(10.0)
        out = s.image.outputs()
        assert out["status_word"] == Status.STOPPED
        assert all(out[f"correction_q{i}"] == 0.0 for i in range(1, 7))
        assert isinstance(s.task.error, OSError)
    finally:
        s.stop()


def test_stop_publishes_the_stopped_state(tmp_path):
    cfg = load_config(write_config(tmp_path, {"plc": {"port": free_port()}}))
    s = Service(cfg)
    s.start()
    assert wait_for(lambda: s.info.cycle_count > 20)
    s.stop()
    out = s.image.outputs()
    assert out["status_word"] & Status.STOPPED and out["task_state"] == 2
    assert out["cycle_count"] >= 20


def test_stop_ramps_the_correction_to_zero_without_a_jump(tmp_path):
    load = np.array([400.0, -300.0, 600.0, 20.0, 15.0, -10.0])
    ramp_s = 0.05
    cfg = load_config(write_config(tmp_path, {
        "source": {"type": "can", "can": {"interface": "virtual", "channel": "svc_stop"}},
        "plc": {"role": "none", "enable_on_start": True},
        "gravity": {"tool": {"mass_kg": 0.0}, "bias": [0.0] * 6},
        "limits": {"max_rate_deg_s": 50.0, "fault_ramp_s": ramp_s},
        "faults": {"overrun_trip_count": 1000, "sensor_timeout_ms": 200}}))
    with VirtualAtiSensor(can.Bus(interface="virtual", channel="svc_stop"), AtiProtocol(), lambda t: load):
        s = Service(cfg)
        record, work = [], s.work

        def recording_work(t, exceeded):
            go_on = work(t, exceeded)
            record.append((t, [getattr(s.record, f"correction_q{i}") for i in range(1, 7)]))
            return go_on

        s.work = recording_work
        s.start()
        try:
            comp = s.cycle
            assert wait_for(lambda: comp.status_word & 0x2 and abs(comp.correction[0]) > 1e-4
                            and np.allclose(comp.correction, comp.dq_deg, atol=1e-9))
        finally:
            n0 = len(record)
            s.stop()
    out = s.image.outputs()
    final = [out[f"correction_q{i}"] for i in range(1, 7)]
    assert out["status_word"] & Status.STOPPED and final == [0.0] * 6
    t = np.array([r[0] for r in record[n0 - 1:]])
    corr = np.array([r[1] for r in record[n0 - 1:]])
    start = np.abs(corr[0])
    assert start.max() > 1e-4
    # every step of the stop is within the ramp's rate, and the last value the cycle published is zero
    steps = np.abs(np.diff(corr, axis=0))
    assert np.all(steps <= start / ramp_s * np.diff(t)[:, None] + 1e-9)
    assert np.all(corr[-1] == 0.0)
