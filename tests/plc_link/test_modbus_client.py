"""The client role: the service writes its outputs into a PLC's registers and reads the PLC's inputs."""

from __future__ import annotations

import asyncio
import struct
import threading
import time

import pytest
from pymodbus.client import ModbusTcpClient
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from hil.testing import CONFIG, free_port, write_config
from io_process.server import IoSettings, IoThread
from plc_link.errors import PlcConnectionError
from plc_link.image import ProcessImage
from plc_link.modbus_client import ModbusClient
from plc_link.register_map import RegisterMap
from plc_link.settings import PlcClientSettings, PlcSettings
from service.app import Service
from service.config import load_config

pytestmark = pytest.mark.realtime

BASE = 0x8000      # the PLC's input registers the service reads (TF6250 GVL.mb_Input_Registers)
OUT = 0x3000       # the PLC's holding registers the service writes (TF6250 %MW area)


class PlcMemory:
    """A PLC's Modbus memory, served by a real pymodbus server in a thread: holding registers anyone may
    write, and input registers the PLC program fills (``inputs``, address -> word)."""

    def __init__(self, port: int, answer_after_s: float = 0.0):
        self.port, self.inputs = port, {}
        self.answer_after_s = answer_after_s
        self.in_flight = self.most_in_flight = 0
        self.writes: list[list[int]] = []
        self.serving = threading.Event()            # set as a request's answer begins
        self._loop = asyncio.new_event_loop()
        self._ready = threading.Event()
        self._thread = threading.Thread(target=self._loop.run_until_complete, args=(self._serve(),), daemon=True)

    async def _action(self, fc, start, address, count, registers, set_values):
        self.in_flight += 1
        self.most_in_flight = max(self.most_in_flight, self.in_flight)
        self.serving.set()
        if self.answer_after_s:
            await asyncio.sleep(self.answer_after_s)
        self.in_flight -= 1
        if fc == 16:
            self.writes.append(list(set_values))
        if fc == 4:
            registers[address - start: address - start + count] = [self.inputs.get(a, 0)
                                                                  for a in range(address, address + count)]

    async def _serve(self):
        device = SimDevice(0, simdata=[SimData(0, count=0x10000, values=0, datatype=DataType.REGISTERS)],
                           action=self._action)
        self.server = ModbusTcpServer(device, address=("127.0.0.1", self.port))
        await self.server.serve_forever(background=True)
        self._stopped = asyncio.Event()
        self._ready.set()
        await self._stopped.wait()
        await self.server.shutdown()

    def __enter__(self):
        self._thread.start()
        assert self._ready.wait(10)
        return self

    def __exit__(self, *exc):
        self._loop.call_soon_threadsafe(self._stopped.set)
        self._thread.join(10)
        self._loop.close()


@pytest.fixture()
def plc():
    """A PLC's Modbus memory and a client of it."""
    with PlcMemory(free_port()) as memory:
        client = ModbusTcpClient("127.0.0.1", port=memory.port, timeout=2)
        assert client.connect()
        try:
            yield memory.port, client, memory
        finally:
            client.close()


def f32_words(x):
    return list(struct.unpack("<HH", struct.pack("<f", x)))


def test_service_in_client_role_exchanges_with_the_plc(tmp_path, plc):
    port, plc_client, device = plc
    words = [0x1, 1]
    for v in (10.0, -80.0, 100.0, 20.0, 40.0, 30.0):
        words += f32_words(v)
    device.inputs.update({BASE + k: w for k, w in enumerate(words)})     # the PLC program fills its inputs
    cfg = load_config(write_config(tmp_path, {"plc": {"role": "client", "port": port, "client": {"period_ms": 5}},
                                              "faults": {"overrun_trip_count": 1000,
                                                         "plc_heartbeat_timeout_ms": 0}}))
    s = Service(cfg)
    s.start()
    try:
        seen, deadline = [], time.monotonic() + 30.0     # until the count has risen once: a loaded host starts late
        while not (len(seen) >= 2 and seen[-1] > seen[0]) and time.monotonic() < deadline:
            r = plc_client.read_holding_registers(OUT, count=0x40).registers
            if r[4] | (r[5] << 16):
                seen.append(r[4] | (r[5] << 16))
            time.sleep(0.02)
        assert len(seen) >= 2 and seen[-1] > seen[0], seen   # the cycle count arrives in the PLC and rises
        time.sleep(0.2)
        r = plc_client.read_holding_registers(OUT, count=0x40).registers
        corr = [struct.unpack("<f", struct.pack("<HH", *r[0x10 + 2 * i:0x12 + 2 * i]))[0] for i in range(6)]
        assert max(abs(c) for c in corr) > 1e-4       # q and enable were read from the PLC
        assert r[1] & 0x2                             # correction active
    finally:
        s.stop()
    r = plc_client.read_holding_registers(OUT, count=4).registers
    assert r[1] & 0x40 and r[3] == 2                  # the PLC sees the service stopped


def test_stop_lets_the_exchange_in_flight_finish_then_writes_the_final_state_once():
    """The stop comes while the PLC is still answering a request (it takes 100 ms for each). The
    final write must not go out behind it: that is two requests at once, and pymodbus' own server
    drops both when they arrive together, so the PLC never sees the stopped state."""
    image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    with PlcMemory(free_port(), answer_after_s=0.1) as device:
        async def run():
            client = ModbusClient(image, "127.0.0.1", device.port, period_s=0.005, timeout_s=5.0)
            await client.start()
            await asyncio.to_thread(device.serving.wait)      # a request is being answered
            await client.stop()
            return client, list(image.to_plc_words())

        try:
            client, final = asyncio.run(run())
        finally:
            image.close()
    assert device.most_in_flight == 1                     # one request at a time, the stop's included
    assert device.writes[-1] == final                     # the final state was written last
    assert client.errors.total == 0 and not client.final_write_failed


def test_a_stop_whose_final_write_goes_unanswered_says_so(caplog):
    """The PLC is gone when the service stops: the stop still ends, and the log names the PLC whose
    stopped state may be missing (never in silence)."""
    image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    device = PlcMemory(free_port())

    async def run():
        with device:
            client = ModbusClient(image, "127.0.0.1", device.port, period_s=0.005, timeout_s=0.5)
            await client.start()
            await asyncio.to_thread(device.serving.wait)   # the exchange runs
        await client.stop()                                # the PLC's server has shut down
        return client

    try:
        client = asyncio.run(run())
    finally:
        image.close()
    assert client.final_write_failed
    assert f"the stopped state may not have reached the PLC at 127.0.0.1:{device.port}" in caplog.text


def test_unreachable_plc_is_a_clear_error():
    image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    settings = IoSettings(plc=PlcSettings(role="client", port=free_port(), client=PlcClientSettings(timeout_s=0.5)))
    try:
        with pytest.raises(PlcConnectionError, match="cannot connect to the PLC"):
            IoThread(image, settings).start()
    finally:
        image.close()
