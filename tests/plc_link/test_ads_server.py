"""The ADS server on a loop of this process, with raw AMS frames: each cycle's notifications go out once,
stamped with that cycle's time; a stalled or non-reading client cannot hold the server."""

from __future__ import annotations

import asyncio
import struct

import pytest

from plc_link.ads import AdsServer, AdsSettings, ams
from plc_link.contract import to_plc
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from testlib.ads_child import MAP, map_variant

pytestmark = pytest.mark.realtime

NET = "5.6.7.11.1.1"
SRC = ams.net_id_bytes("127.0.0.1.1.1")


def request(cmd: int, payload: bytes, invoke: int = 1) -> bytes:
    return ams.request_frame(ams.net_id_bytes(NET), 851, SRC, 30001, cmd, payload, invoke)


async def read_frame(reader: asyncio.StreamReader) -> tuple[ams.AmsHeader, bytes]:
    _, length = ams.TCP_HEADER.unpack(await reader.readexactly(6))
    body = await reader.readexactly(length)
    return ams.AmsHeader.parse(body), body[32:]


def run(coro_fn, **settings):
    async def main():
        image = ProcessImage(RegisterMap.from_yaml(MAP))
        server = AdsServer(image, AdsSettings(net_id=NET, port=0, **settings))
        await server.start()
        try:
            return await coro_fn(image, server)
        finally:
            await server.stop()
            image.close()
    return asyncio.run(main())


def test_on_cycle_sends_each_cycle_once_stamped_with_its_time():
    async def body(image, server):
        reader, writer = await asyncio.open_connection(*server.address)
        add = struct.pack("<IIIIII16x", 0x4020, 8, 4, ams.TRANS_SERVER_CYCLE, 0, 0)   # cycle_count, every cycle
        writer.write(request(ams.ADD_NOTIFICATION, add))
        h, payload = await read_frame(reader)
        result, handle = ams.ADD_NOTE_RES.unpack(payload)
        assert result == 0
        stamps = [1_700_000_000_123_456_700 + i * 1_000_000 for i in range(3)]
        for i, stamp in enumerate(stamps):
            image.publish(to_plc(cycle_count=i + 1), stamp_ns=stamp)
            server.on_cycle()
            server.on_cycle()                       # the same cycle again: nothing more is sent
        got = []
        for _ in stamps:
            h, payload = await read_frame(reader)
            assert h.command == ams.DEVICE_NOTIFICATION and not h.flags & ams.FLAG_RESPONSE
            assert (h.target, h.target_port) == (SRC, 30001)
            _, n_stamps = ams.NOTE_HEAD.unpack_from(payload)
            filetime, n_samples = ams.STAMP_HEAD.unpack_from(payload, 8)
            h_note, size = ams.SAMPLE_HEAD.unpack_from(payload, 20)
            assert (n_stamps, n_samples, h_note, size) == (1, 1, handle, 4)
            got.append((filetime, struct.unpack_from("<I", payload, 28)[0]))
        # no fourth frame: the next thing on the wire is the answer to this request
        writer.write(request(ams.READ_STATE, b"", invoke=99))
        h, _ = await read_frame(reader)
        assert h.invoke_id == 99
        writer.close()
        return got

    got = run(body, notify_poll_s=0.1)
    assert got == [(s // 100 + 116_444_736_000_000_000, i + 1) for i, s in enumerate(
        [1_700_000_000_123_456_700 + i * 1_000_000 for i in range(3)])]


def test_a_frame_left_unfinished_closes_the_connection():
    async def body(image, server):
        reader, writer = await asyncio.open_connection(*server.address)
        writer.write(ams.TCP_HEADER.pack(0, 100) + bytes(10))          # 10 of 100 announced bytes
        rest = await asyncio.wait_for(reader.read(), 10.0)              # EOF: closed, nothing answered
        writer.close()
        return rest

    assert run(body, frame_timeout_s=0.2) == b""


def test_stop_returns_with_a_client_that_does_not_read():
    async def body(image, server):
        _reader, writer = await asyncio.open_connection(*server.address)
        read_all = request(ams.READ, struct.pack("<III", 0x4020, 0, 1024))
        try:
            for _ in range(2000):                # until the server's answers back up (a bound, not a time)
                writer.write(read_all * 50)
                await asyncio.sleep(0.005)
                if any(c.writer.transport.get_write_buffer_size() for c in server.connections):
                    break
            stuck = [c.writer.transport.get_write_buffer_size() > 0 for c in server.connections]
            await asyncio.wait_for(server.stop(), 10.0)          # returning at all is the property
        finally:
            writer.transport.abort()
        return stuck, server.connections

    assert run(body) == ([True], set())


def test_cycle_times_count_on_the_cycles_stamps_and_on_change_sends_changes_only():
    t0 = 1_700_000_000_000_000_000

    async def body(image, server):
        reader, writer = await asyncio.open_connection(*server.address)
        handles = {}
        for name, offset, mode, cycle_100ns in (("cyclic", 8, ams.TRANS_SERVER_CYCLE, 50_000),     # 5 ms
                                                 ("change", 32, ams.TRANS_SERVER_ON_CHANGE, 0)):
            writer.write(request(ams.ADD_NOTIFICATION, struct.pack("<IIIIII16x", 0x4020, offset, 4, mode, 0,
                                                                   cycle_100ns)))
            _, payload = await read_frame(reader)
            result, handles[name] = ams.ADD_NOTE_RES.unpack(payload)
            assert result == 0
        for cycle in range(1, 13):                                  # 12 cycles, 1 ms apart
            image.publish(to_plc(cycle_count=cycle, correction_q1=float(cycle // 3)),
                          stamp_ns=t0 + (cycle - 1) * 1_000_000)
            server.on_cycle()
        writer.write(request(ams.READ_STATE, b"", invoke=99))
        sent = {"cyclic": [], "change": []}
        names = {v: k for k, v in handles.items()}
        while True:
            h, payload = await read_frame(reader)
            if h.invoke_id == 99 and h.flags & ams.FLAG_RESPONSE:
                break
            filetime, n = ams.STAMP_HEAD.unpack_from(payload, 8)
            pos = 20
            for _ in range(n):
                handle, size = ams.SAMPLE_HEAD.unpack_from(payload, pos)
                fmt = "<I" if names[handle] == "cyclic" else "<f"
                sent[names[handle]].append(((filetime - 116_444_736_000_000_000) * 100 - t0,
                                            struct.unpack_from(fmt, payload, pos + 8)[0]))
                pos += 8 + size
        writer.close()
        return sent

    sent = run(body, notify_poll_s=0.1)
    ms = 1_000_000
    assert sent["cyclic"] == [(0, 1), (5 * ms, 6), (10 * ms, 11)]
    assert sent["change"] == [(0, 0.0), (2 * ms, 1.0), (5 * ms, 2.0), (8 * ms, 3.0), (11 * ms, 4.0)]


def test_runtime_state_and_symbol_version_notify_their_value_then_changes_only(tmp_path):
    async def body(image, server):
        reader, writer = await asyncio.open_connection(*server.address)
        names = {}
        for name, group, length in (("state", 0xF100, 4), ("version", 0xF008, 1)):    # as ads-client subscribes
            writer.write(request(ams.ADD_NOTIFICATION, struct.pack("<IIIIII16x", group, 0, length,
                                                                   ams.TRANS_SERVER_ON_CHANGE, 0, 0)))
            _, payload = await read_frame(reader)
            result, handle = ams.ADD_NOTE_RES.unpack(payload)
            assert result == 0
            names[handle] = name
        versions = [server.device.symbol_version]
        for cycle in range(1, 41):                                  # the task runs 10 cycles, then stops
            if cycle == 21:                                         # the same symbols installed again
                versions.append(server.device.install(RegisterMap.from_yaml(MAP)))
            if cycle == 31:                                         # one symbol less, as a live reload would
                versions.append(server.device.install(map_variant(tmp_path, drop="period_jitter_us")))
            image.publish(to_plc(cycle_count=cycle, task_state=1 if cycle <= 10 else 2))
            server.on_cycle()
        writer.write(request(ams.READ_STATE, b"", invoke=99))
        sent = {"state": [], "version": []}
        while True:
            h, payload = await read_frame(reader)
            if h.invoke_id == 99 and h.flags & ams.FLAG_RESPONSE:
                assert ams.STATE_RES.unpack(payload) == (0, ams.ADSSTATE_STOP, 0)
                break
            _, n = ams.STAMP_HEAD.unpack_from(payload, 8)
            pos = 20
            for _ in range(n):
                handle, size = ams.SAMPLE_HEAD.unpack_from(payload, pos)
                sent[names[handle]].append(payload[pos + 8: pos + 8 + size])
                pos += 8 + size
        writer.close()
        return sent, versions

    sent, versions = run(body, notify_poll_s=0.1)
    assert sent["state"] == [struct.pack("<HH", ams.ADSSTATE_RUN, 0), struct.pack("<HH", ams.ADSSTATE_STOP, 0)]
    first, same, fewer = versions
    assert same == first != fewer
    assert sent["version"] == [bytes([first]), bytes([fewer])]     # once per symbol set, at the cycle after it
