"""No reader ever sees two cycles mixed: a writer process publishes as fast as it can, readers check.

Every value of cycle n is a function of n alone, so a read that mixes words of two cycles shows values
of two different n. The writer runs in a process of its own (as the cycle does); the readers are a
Modbus client through the I/O server, and the image's own readers.
"""

from __future__ import annotations

import multiprocessing
import time

import numpy as np
import pytest
from pymodbus.client import ModbusTcpClient

from hil.testing import CONFIG, free_port
from io_process.server import IoSettings, IoThread
from plc_link.contract import ToPlc
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from plc_link.settings import PlcSettings

pytestmark = pytest.mark.realtime

MAP = RegisterMap.from_yaml(CONFIG / "registers.yaml")
# the reads go on until each reader has seen this many different cycles, each whole: a loaded machine that lets
# the writer publish less often only makes that take longer; the deadline is for a writer that stopped
DISTINCT = 200
DEADLINE_S = 300.0


def record(n: int) -> ToPlc:
    """Cycle n's record: every field a function of n that float32 and the integer types carry exactly."""
    return ToPlc._make([float((n + k) % 60000) for k in range(len(ToPlc._fields))])


def writer(image: ProcessImage, stop, published, started) -> None:
    n = 0
    try:
        while not stop.is_set():
            image.publish(record(n))
            n += 1
            if n == 1:
                started.set()
        published.value = n
    finally:
        image.close()


def cycles_seen(values: dict[str, float]) -> set[int]:
    """The n each value belongs to."""
    return {int(values[f] - k) % 60000 for k, f in enumerate(ToPlc._fields) if f in values}


def test_no_reader_sees_two_cycles_mixed():
    image = ProcessImage(MAP)
    ctx = multiprocessing.get_context("spawn")
    stop, started, published = ctx.Event(), ctx.Event(), ctx.Value("q", 0)
    proc = ctx.Process(target=writer, args=(image, stop, published, started))
    port = free_port()
    io = IoThread(image, IoSettings(plc=PlcSettings(port=port)))
    io.start()
    codec = MAP.codecs["to_plc"]
    seen: set[int] = set()          # the cycles the Modbus client read, each whole
    seen_image: set[int] = set()    # those the image's own reader read
    try:
        proc.start()
        assert started.wait(60)
        with ModbusTcpClient("127.0.0.1", port=port, timeout=5) as c:
            assert c.connect()
            deadline = time.monotonic() + DEADLINE_S
            while min(len(seen), len(seen_image)) < DISTINCT and time.monotonic() < deadline:
                r = c.read_input_registers(codec.start, count=codec.words)
                assert not r.isError()
                values = dict(zip(codec.names, codec.decode(r.registers)))
                if any(values.values()):        # else the writer has not published yet
                    ns = cycles_seen(values)
                    assert len(ns) == 1, f"one read holds values of cycles {sorted(ns)}"
                    seen |= ns
                out = image.outputs()
                if any(out.values()):
                    ns = cycles_seen(out)
                    assert len(ns) == 1, f"the image's reader saw cycles {sorted(ns)}"
                    seen_image |= ns
    finally:
        stop.set()
        proc.join(20)
        io.stop()
        image.close()
    assert proc.exitcode == 0
    # the reads overlapped the writer: each reader saw DISTINCT different cycles whole (the loop waited for
    # them), while the writer published more still
    assert min(len(seen), len(seen_image)) >= DISTINCT, \
        f"in {DEADLINE_S:g} s the readers saw {len(seen)} and {len(seen_image)} cycles: the writer stalled"
    assert published.value > len(seen | seen_image)


def test_the_cycle_reads_each_plc_write_whole():
    """The cycle side's reader against the I/O side writing the PLC's block as fast as it can."""
    image = ProcessImage(MAP)
    inp = MAP.codecs["from_plc"]
    ctx = multiprocessing.get_context("spawn")
    stop = ctx.Event()
    started = ctx.Event()
    proc = ctx.Process(target=plc_writer, args=(image, stop, started))
    checked = 0
    try:
        proc.start()
        assert started.wait(60)
        for _ in range(20000):
            v = image.inputs()
            if v.command_word == 0:         # the writer has not written yet
                continue
            base = v.plc_heartbeat
            assert [v.q1, v.q2, v.q3, v.q4, v.q5, v.q6] == [float(base + k) for k in range(6)], v
            assert v.payload_index == base, v
            checked += 1
    finally:
        stop.set()
        proc.join(20)
        image.close()
    assert proc.exitcode == 0
    assert checked > 10000 and inp.words == 15


def plc_writer(image: ProcessImage, stop, started) -> None:
    inp = image.in_codec
    n = 0
    try:
        while not stop.is_set():
            values = {"command_word": 1, "plc_heartbeat": n % 60000, "payload_index": n % 60000,
                      **{f"q{i + 1}": float(n % 60000 + i) for i in range(6)}}
            image.write_block(inp.encode([values[k] for k in inp.names]))
            n += 1
            if n == 1:
                started.set()
    finally:
        image.close()


def test_a_published_record_reads_back_by_name():
    image = ProcessImage(MAP)
    try:
        image.publish(record(1234))
        out = image.outputs()
        expected = record(1234)._asdict()
        assert all(np.isclose(out[k], expected[k]) for k in out)
    finally:
        image.close()


def test_a_writer_taking_over_after_one_killed_mid_write_leaves_every_write_readable():
    """An I/O process killed between its two sequence increments leaves that buffer's count odd; the next
    one takes the inputs over (`take_over_inputs`) and the cycle reads each of its writes, none stale."""
    rmap = RegisterMap.from_yaml(CONFIG / "registers.yaml")
    image = ProcessImage(rmap)
    try:
        start = rmap.blocks["from_plc"].start
        image.write("holding_registers", start, [1])
        h = image._h
        h[5 + 1 + ((int(h[5]) + 1) & 1)] += 1        # the next writer's buffer, left half-written
        image.take_over_inputs()
        for k in range(2, 8):
            image.write("holding_registers", start, [k])
            assert image.inputs().command_word == k
        assert image.stale_reads == 0
    finally:
        image.close()


def test_a_map_without_payload_index_reads_it_as_0(tmp_path):
    """payload_index is optional in a map: a site map from before the payload table selects set 0."""
    from stiffness.files.yaml_schema import dump_yaml, read_yaml

    data = read_yaml(CONFIG / "registers.yaml")
    data["from_plc"]["registers"] = [r for r in data["from_plc"]["registers"] if r["name"] != "payload_index"]
    (tmp_path / "old.yaml").write_text(dump_yaml(data))
    image = ProcessImage(RegisterMap.from_yaml(tmp_path / "old.yaml"))
    try:
        image.write_values({"q1": 12.5})
        v = image.inputs()
        assert v.payload_index == 0.0 and v.q1 == 12.5
    finally:
        image.close()
