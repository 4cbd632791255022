"""The Modbus server with a real pymodbus client: reads, PLC writes, refused writes (0x02, no change)."""

from __future__ import annotations

import struct

import pytest
from pymodbus.client import ModbusTcpClient

from hil.testing import CONFIG, free_port
from io_base.errors import PlcError
from io_process.server import IoSettings, IoThread
from plc_link.contract import ToPlc
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from plc_link.settings import PlcSettings

BASE = 0x8000


@pytest.fixture()
def served():
    image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    port = free_port()
    server = IoThread(image, IoSettings(plc=PlcSettings(port=port)))
    server.start()
    client = ModbusTcpClient("127.0.0.1", port=port, timeout=2)
    assert client.connect()
    try:
        yield image, client
    finally:
        client.close()
        server.stop()
        image.close()


def record(**values) -> ToPlc:
    """A to_plc record: zero but for ``values``."""
    return ToPlc(**{f: 0.0 for f in ToPlc._fields} | values)


def test_client_reads_what_the_cycle_publishes(served):
    image, client = served
    image.publish(record(cycle_count=123456, correction_q3=-0.0125))
    r = client.read_input_registers(BASE, count=32)
    assert not r.isError()
    assert r.registers[4] | (r.registers[5] << 16) == 123456
    q3 = struct.unpack("<f", struct.pack("<HH", *r.registers[0x14:0x16]))[0]
    assert q3 == pytest.approx(-0.0125)


def test_plc_writes_reach_the_cycle(served):
    image, client = served
    words = [0x1, 42] + list(struct.unpack("<HH", struct.pack("<f", 12.5))) * 6
    assert not client.write_registers(BASE, words).isError()
    vals = image.inputs()._asdict()
    assert vals["command_word"] == 1 and vals["plc_heartbeat"] == 42 and vals["q6"] == 12.5
    assert not client.write_register(BASE + 1, 43).isError()
    assert image.inputs()._asdict()["plc_heartbeat"] == 43


@pytest.mark.parametrize("address, values", [
    (BASE + 0x20, [1]),             # a holding register the map does not give to the PLC
    (0x0000, [1]),                  # outside every block
    (BASE + 0x0C, [1, 2, 3, 4]),    # starts on q6, runs past the PLC's registers
    (BASE + 0xFF, [1, 2]),          # runs past the end of the block
])
def test_writes_outside_plc_registers_get_0x02_and_change_nothing(served, address, values):
    image, client = served
    before_h = client.read_holding_registers(BASE, count=16).registers
    before_i = client.read_input_registers(BASE, count=64).registers
    r = client.write_registers(address, values)
    assert r.isError() and r.exception_code == 0x02
    refused = 1
    if address not in image.writable:
        r = client.write_register(address, values[0])
        assert r.isError() and r.exception_code == 0x02
        refused += 1
    assert client.read_holding_registers(BASE, count=16).registers == before_h
    assert client.read_input_registers(BASE, count=64).registers == before_i
    assert image.refused_writes == refused


@pytest.mark.parametrize("address, values, fc6", [
    (BASE + 2, [0x1234], True),        # FC6 to the first word of the float32 q1
    (BASE + 3, [0x1234], True),        # FC6 to its second word
    (BASE + 1, [7, 0x1234], False),    # heartbeat and half of q1: ends inside it
    (BASE + 3, [0x1234, 1, 2], False), # starts inside q1, covers q2 whole
])
def test_writes_covering_half_a_32_bit_register_get_0x02_and_change_nothing(served, address, values, fc6):
    image, client = served
    words = [0x1, 42] + list(struct.unpack("<HH", struct.pack("<f", 12.5))) * 6
    assert not client.write_registers(BASE, words).isError()
    before = client.read_holding_registers(BASE, count=16).registers
    r = client.write_register(address, values[0]) if fc6 else client.write_registers(address, values)
    assert r.isError() and r.exception_code == 0x02
    assert client.read_holding_registers(BASE, count=16).registers == before
    assert image.inputs()._asdict()["q1"] == 12.5
    assert image.refused_writes == 1


def test_reads_outside_the_map_get_0x02(served):
    _image, client = served
    r = client.read_input_registers(0x0000, count=4)
    assert r.isError() and r.exception_code == 0x02
    r = client.read_holding_registers(BASE + 0xFE, count=4)
    assert r.isError() and r.exception_code == 0x02


def test_busy_port_is_a_clear_error():
    image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    settings = IoSettings(plc=PlcSettings(port=free_port()))
    first = IoThread(image, settings)
    first.start()
    try:
        with pytest.raises(PlcError, match=f"cannot serve Modbus TCP on 127.0.0.1:{settings.plc.port}"):
            IoThread(image, settings).start()
    finally:
        first.stop()
        image.close()


def test_coils_and_discrete_inputs_are_refused(served):
    _, client = served
    before = client.read_holding_registers(BASE, count=16).registers
    r = client.write_coil(BASE, True)
    assert r.isError() and r.exception_code == 0x01
    r = client.read_coils(BASE, count=8)
    assert r.isError() and r.exception_code == 0x01
    r = client.read_discrete_inputs(BASE, count=8)
    assert r.isError() and r.exception_code == 0x01
    assert client.read_holding_registers(BASE, count=16).registers == before


def test_garbage_on_the_socket_does_not_disturb_the_server(served):
    import socket

    _, client = served
    port = client.comm_params.port
    with socket.create_connection(("127.0.0.1", port), timeout=2) as s:
        s.sendall(b"\x00\x01\x00\x00\x00\xff\x01\x03garbage" + bytes(range(256)))
        s.settimeout(0.5)
        try:
            s.recv(1024)
        except (TimeoutError, ConnectionError):
            pass
    r = client.read_input_registers(BASE, count=4)
    assert not r.isError()
