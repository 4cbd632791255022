"""The client role: the service writes its outputs into a PLC's registers and reads the PLC's inputs."""

from __future__ import annotations

import struct
import time

import pytest
from pymodbus.client import ModbusTcpClient
from pymodbus.datastore import ModbusDeviceContext, ModbusSequentialDataBlock, ModbusServerContext

from plc_interface.errors import PlcConnectionError
from plc_interface.image import RegisterImage
from plc_interface.modbus_client import ModbusClientThread
from plc_interface.modbus_server import ModbusServerThread
from plc_interface.register_map import RegisterMap
from service.app import Service
from service.config import load_config
from service.testing import CONFIG, free_port, write_config

BASE = 0x8000      # the PLC's input registers the service reads (TF6250 GVL.mb_Input_Registers)
OUT = 0x3000       # the PLC's holding registers the service writes (TF6250 %MW area)


@pytest.fixture()
def plc():
    """A PLC's Modbus memory: plain holding registers, served by a real pymodbus server."""
    device = ModbusDeviceContext(hr=ModbusSequentialDataBlock(0, [0] * 0x10000),
                                 ir=ModbusSequentialDataBlock(0, [0] * 0x10000))
    server = ModbusServerThread(None, "127.0.0.1", free_port(), context=ModbusServerContext(devices=device))
    server.start()
    client = ModbusTcpClient("127.0.0.1", port=server.port, timeout=2)
    assert client.connect()
    try:
        yield server.port, client, device
    finally:
        client.close()
        server.stop()


def f32_words(x):
    return list(struct.unpack("<HH", struct.pack("<f", x)))


def test_service_in_client_role_exchanges_with_the_plc(tmp_path, plc):
    port, plc_client, device = plc
    words = [0x1, 1]
    for v in (10.0, -80.0, 100.0, 20.0, 40.0, 30.0):
        words += f32_words(v)
    device.setValues(4, BASE, words)              # the PLC program fills its input registers
    cfg = load_config(write_config(tmp_path, {"plc": {"role": "client", "port": port, "client": {"period_ms": 5}},
                                              "faults": {"overrun_trip_count": 1000,
                                                         "plc_heartbeat_timeout_ms": 0}}))
    s = Service(cfg)
    s.start()
    try:
        counts = []
        for _ in range(100):
            r = plc_client.read_holding_registers(OUT, count=0x40).registers
            counts.append(r[4] | (r[5] << 16))
            if counts[-1] > 200:
                break
            time.sleep(0.02)
        seen = [c for c in counts if c > 0]
        assert len(seen) >= 2 and seen[-1] > seen[0]   # the cycle count arrives in the PLC and rises
        time.sleep(0.2)
        r = plc_client.read_holding_registers(OUT, count=0x40).registers
        corr = [struct.unpack("<f", struct.pack("<HH", *r[0x10 + 2 * i:0x12 + 2 * i]))[0] for i in range(6)]
        assert max(abs(c) for c in corr) > 1e-4       # q and enable were read from the PLC
        assert r[1] & 0x2                             # correction active
    finally:
        s.stop()
    r = plc_client.read_holding_registers(OUT, count=4).registers
    assert r[1] & 0x40 and r[3] == 2                  # the PLC sees the service stopped


def test_unreachable_plc_is_a_clear_error():
    image = RegisterImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    with pytest.raises(PlcConnectionError, match="cannot connect to the PLC"):
        ModbusClientThread(image, "127.0.0.1", free_port(), timeout_s=0.5).start()
