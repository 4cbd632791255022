"""The assembled service: a live CAN source with the virtual sensor, and the error policy of the cycle."""

from __future__ import annotations

import time

import can
import numpy as np

from plc_interface.register_map import RegisterMap  # noqa: F401  (the service imports it too)
from service.app import Service
from service.ati import AtiProtocol
from service.config import load_config
from service.pipeline import ST_STOPPED
from service.sources.replay import ReplaySource
from service.sources.virtual_sensor import VirtualAtiSensor
from service.testing import free_port, write_config


def wait_for(pred, timeout=10.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(0.01)
    return False


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
            assert wait_for(lambda: s.compensator.status_word & 0x2 and abs(s.compensator.correction[0]) > 1e-4)
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
        assert out["status_word"] == ST_STOPPED
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
    assert out["status_word"] & ST_STOPPED and out["task_state"] == 2
    assert out["cycle_count"] >= 20
