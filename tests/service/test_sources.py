"""F/T sources: replay (fast and real-time pacing, loop), live CAN with the virtual sensor, tare."""

from __future__ import annotations

import time

import can
import numpy as np
import pytest

from hil.demo_log import write_log
from hil.testing import free_port, write_config
from hil.virtual_sensor import VirtualAtiSensor
from plc_link.contract import Command
from service.ati import AtiProtocol
from service.errors import SensorTimeout, SourceError
from service.pipeline import Cycle
from service.sources.can_source import CanSource, open_bus
from service.sources.replay import ReplaySource, read_log

KW = {"timeout_s": 0.01, "max_force_N": 2500.0, "max_torque_Nm": 250.0}


def ramp_log(path, n=50):
    w = np.zeros((n, 6))
    w[:, 0] = np.arange(n)            # Fx = sample index, N
    write_log(path, w)
    return w


@pytest.mark.parametrize("suffix", [".blf", ".asc", ".log", ".csv"])
def test_replay_fast_gives_one_sample_per_poll_in_order(tmp_path, suffix):
    w = ramp_log(tmp_path / f"r{suffix}")
    src = ReplaySource(read_log(tmp_path / f"r{suffix}"), pacing="fast", loop=False, protocol=AtiProtocol(), **KW)
    got = [src.poll(k * 1e-3)[0].wrench[0] for k in range(50)]
    np.testing.assert_allclose(got, w[:, 0])


def test_replay_realtime_follows_the_given_clock(tmp_path):
    ramp_log(tmp_path / "r.blf", 100)
    src = ReplaySource(read_log(tmp_path / "r.blf"), pacing="realtime", loop=False, protocol=AtiProtocol(), **KW)
    src.poll(0.0)
    reading, errors = src.poll(0.0205)        # samples logged at 0, 1, ..., 20 ms (+0.4 ms for the frames)
    assert reading.wrench[0] == 20.0 and errors == []


def test_replay_loops(tmp_path):
    ramp_log(tmp_path / "r.blf", 10)
    src = ReplaySource(read_log(tmp_path / "r.blf"), pacing="fast", loop=True, protocol=AtiProtocol(), **KW)
    got = [src.poll(k * 1e-3)[0].wrench[0] for k in range(25)]
    assert got == [float(k % 10) for k in range(25)]


def test_replay_end_without_loop_times_out(tmp_path):
    ramp_log(tmp_path / "r.blf", 5)
    src = ReplaySource(read_log(tmp_path / "r.blf"), pacing="fast", loop=False, protocol=AtiProtocol(), **KW)
    for k in range(5):
        src.poll(k * 1e-3)
    _, errors = src.poll(0.02)
    assert any(isinstance(e, SensorTimeout) for e in errors)


def test_replay_file_errors_are_clear(tmp_path):
    with pytest.raises(SourceError, match="not found"):
        read_log(tmp_path / "missing.blf")
    (tmp_path / "x.txt").write_text("hello")
    with pytest.raises(SourceError, match="is not one of"):
        read_log(tmp_path / "x.txt")
    (tmp_path / "bad.asc").write_text("this is not a CAN log\n")
    with pytest.raises(SourceError):
        read_log(tmp_path / "bad.asc")


def test_can_source_reads_the_virtual_sensor_and_biases_it():
    load = np.array([120.0, -40.0, 300.0, 4.0, -2.0, 1.5])
    p = AtiProtocol()
    with VirtualAtiSensor(can.Bus(interface="virtual", channel="t_can"), p, lambda t: load) as sensor:
        src = CanSource(can.Bus(interface="virtual", channel="t_can"), protocol=p, **KW)
        try:
            readings = []
            for k in range(200):
                r, errors = src.poll(k * 1e-3)
                assert not [e for e in errors if not isinstance(e, SensorTimeout)]
                if r is not None:
                    readings.append(r.wrench)
                if len(readings) >= 5:
                    break
                time.sleep(0.002)
            np.testing.assert_allclose(readings[-1], load, atol=0.1)
            src.request_bias()
            for _ in range(100):
                r, _ = src.poll(1.0)
                if r is not None and np.abs(r.wrench).max() < 0.1:
                    break
                time.sleep(0.002)
            np.testing.assert_allclose(r.wrench, 0.0, atol=0.1)
            assert sensor.requests >= 5
        finally:
            src.close()


def test_unknown_interface_is_a_clear_error():
    with pytest.raises(SourceError, match="cannot open CAN interface 'nonexistent'"):
        open_bus("nonexistent", "x")


def _loaded_compensator(tmp_path):
    """A compensator that has run 100 cycles on a constant, nonzero wrench from a fast replay."""
    from service.config import load_config
    from service.sources import make_source
    from stiffness.model.stiffness_model import StiffnessModel

    log = tmp_path / "c.blf"
    write_log(log, np.tile([50.0, 20.0, -30.0, 1.0, 2.0, 3.0], (300, 1)))
    cfg = load_config(write_config(tmp_path, {"source": {"replay": {"file": str(log), "pacing": "fast"}}}))
    comp = Cycle.from_config(cfg, StiffnessModel.from_yaml(cfg.resolve(cfg.model.file)))
    src = make_source(cfg)
    q = cfg.plc.initial_q_deg
    for k in range(100):
        comp.step(k * 1e-3, *src.poll(k * 1e-3), Command.ENABLE, k, q)
    assert np.abs(comp.wrench_sensor).max() > 1.0
    return comp, src, q


def test_tare_command_zeroes_the_wrench(tmp_path):
    comp, src, q = _loaded_compensator(tmp_path)
    comp.step(0.1, *src.poll(0.1), Command.ENABLE | Command.TARE, 100, q)
    assert comp.tares == 1
    np.testing.assert_allclose(comp.wrench_sensor, 0.0, atol=1e-9)
    np.testing.assert_allclose(comp.deflection, 0.0, atol=1e-12)


def test_can_source_between_processes_over_udp_multicast():
    """The virtual sensor in its own process, the source here: real CAN frames over udp_multicast."""
    import random
    import socket
    import subprocess
    import sys

    pytest.importorskip("msgpack")
    # a group and port of its own (as hil/run.py does), so parallel runs never hear each other
    channel = f"239.74.{random.randint(1, 254)}.{random.randint(1, 254)}"
    port = free_port(socket.SOCK_DGRAM)
    load = [250.0, -60.0, 410.0, 7.5, -3.0, 2.25]
    proc = subprocess.Popen([sys.executable, "-m", "hil.virtual_sensor", "--interface", "udp_multicast",
                             "--channel", channel, "--port", str(port), "--load", ",".join(map(str, load)), "--seconds", "20"],
                            stdout=subprocess.PIPE, text=True)
    try:
        assert proc.stdout.readline().strip() == "ready"
        src = CanSource(can.Bus(interface="udp_multicast", channel=channel, port=port), protocol=AtiProtocol(), **KW)
        try:
            reading = None
            for k in range(2000):
                r, errors = src.poll(k * 1e-3)
                assert not [e for e in errors if not isinstance(e, SensorTimeout)]
                if r is not None:
                    reading = r
                    break
                time.sleep(0.002)
            assert reading is not None
            np.testing.assert_allclose(reading.wrench, load, atol=0.1)
        finally:
            src.close()
    finally:
        proc.terminate()
        proc.wait(10)
        proc.stdout.close()


def test_error_frames_in_a_log_are_can_frame_errors(tmp_path):
    from service.errors import CanFrameError

    path = tmp_path / "err.asc"
    p = AtiProtocol()
    with can.Logger(str(path)) as log:
        for k in range(3):
            for j, (arb, data) in enumerate(p.encode([1.0, 2.0, 3.0, 0.1, 0.2, 0.3], 0, k)):
                log(can.Message(timestamp=1.0 + k * 1e-3 + j * 1e-4, arbitration_id=arb, data=data,
                                is_extended_id=False))
        log(can.Message(timestamp=1.01, is_error_frame=True, arbitration_id=0x020))
    src = ReplaySource(read_log(path), pacing="realtime", loop=False, protocol=p, **KW)
    src.poll(0.0)
    reading, errors = src.poll(0.05)
    assert reading is not None
    assert any(isinstance(e, CanFrameError) and "error frame" in str(e) for e in errors)


def test_replay_refuses_a_log_without_samples_for_the_base_id(tmp_path):
    ramp_log(tmp_path / "r.blf", 5)                   # written for base id 0x020
    from service.config import load_config
    from service.sources import make_source

    cfg = load_config(write_config(tmp_path, {"source": {"replay": {"file": str(tmp_path / "r.blf"),
                                                                    "pacing": "fast", "loop": True},
                                                         "ati": {"base_id": 0x030}}}))
    with pytest.raises(SourceError, match=r"r\.blf.*0x036.*base_id"):
        make_source(cfg)


def test_replay_fast_loop_poll_returns_after_one_pass_without_a_sample(tmp_path):
    """Frames of the sensor's first half only: a looped fast replay must still return from poll."""
    p = AtiProtocol()
    frames = [(k * 1e-3, p.id_1, p.encode([1.0] * 6, 0, k)[0][1], False) for k in range(7)]
    src = ReplaySource(frames + [(0.01, p.id_2, p.encode([1.0] * 6, 0, 7)[1][1], False)], pacing="fast",
                       loop=True, protocol=p, **KW)
    src.frames = frames                               # the check passed; now the log yields no sample at all
    src.duration = 0.007
    reading, errors = src.poll(0.0)
    assert reading is None and len(errors) <= len(frames)
    reading, _ = src.poll(1e-3)
    assert reading is None


def test_a_tare_edge_in_a_cycle_without_a_sample_applies_to_the_next_sample(tmp_path):
    comp, src, q = _loaded_compensator(tmp_path)
    comp.step(0.1, None, [], Command.ENABLE | Command.TARE, 100, q)       # the edge, but no sample this cycle
    assert comp.tares == 0
    comp.step(0.101, *src.poll(0.101), Command.ENABLE | Command.TARE, 101, q)   # the bit is still high: no new edge
    assert comp.tares == 1
    np.testing.assert_allclose(comp.wrench_sensor, 0.0, atol=1e-9)
    comp.step(0.102, *src.poll(0.102), Command.ENABLE, 102, q)
    assert comp.tares == 1
