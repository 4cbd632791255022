"""What a TwinCAT runtime serves beyond values (issue 20), through pyads (AdsLib) against the server in a
spawn child (ads_child.py): the system service on AMS port 10000, the runtime state (0xF100) and the
symbol version (0xF008) read and subscribed, the data types (0xF00E, 0xF011, counted in 0xF00F) and
the handle by name with the runtime's full answer. ads-client's view: test_ads_node.py; the
notifications of 0xF100 and 0xF008: test_ads_server.py."""

from __future__ import annotations

import ctypes
import struct
from itertools import pairwise

import pyads
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from plc_link.ads.datatypes import BASE_TYPES
from plc_link.ads.session import Device
from plc_link.ads.symbols import TASKINFO_PREFIX, SymbolTable
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from testlib.ads_child import MAP, map_variant

pytestmark = pytest.mark.realtime

NET_ID = "5.6.7.12.1.1"
TABLE = SymbolTable(RegisterMap.from_yaml(MAP))


def raw_read_write(plc, group: int, data: bytes, rlen: int) -> bytes:
    return bytes(plc.read_write(group, 0, ctypes.c_ubyte * rlen, list(data), ctypes.c_ubyte * len(data),
                                return_ctypes=True, check_length=False))


def parse_datatype(raw: bytes) -> tuple[dict, int]:
    """One AdsDatatypeEntry as TcAdsDef.h lays it out (written from the layout, not from the server's code)."""
    (length, version, _hash, _type_hash, size, offs, ads_type, flags,
     n_name, n_type, n_comment, array_dim, sub_items) = struct.unpack_from("<8I5H", raw)
    pos = 42
    name = raw[pos: pos + n_name].decode()
    assert raw[pos + n_name] == 0
    pos += n_name + 1
    typ = raw[pos: pos + n_type].decode()
    pos += n_type + 1 + n_comment + 1
    assert pos <= length
    return {"name": name, "type": typ, "size": size, "offs": offs, "ads": ads_type, "flags": flags,
            "version": version, "array_dim": array_dim, "sub_items": sub_items}, length


def test_system_service_on_port_10000(server):
    system = pyads.Connection(NET_ID, 10000, f"{server.host}:{server.port}")
    system.open()
    try:
        assert system.read_state() == (pyads.ADSSTATE_RUN, 0)
        name, _version = system.read_device_info()
        assert name == "stiffcomp"
        with pytest.raises(pyads.ADSError) as e:        # no client switches the service to config or restarts it
            system.write_control(pyads.ADSSTATE_RECONFIG, 0, 0, pyads.PLCTYPE_INT)
        assert e.value.err_code == 0x701
        with pytest.raises(pyads.ADSError) as e:
            system.read(0x4040, 4, pyads.PLCTYPE_UDINT)       # the PLC's areas are on 851, not here
        assert e.value.err_code == 0x702
        assert system.read_state() == (pyads.ADSSTATE_RUN, 0)     # still served
    finally:
        system.close()
    other = pyads.Connection(NET_ID, 10001, f"{server.host}:{server.port}")
    other.open()
    try:
        with pytest.raises(pyads.ADSError) as e:
            other.read_state()
        assert e.value.err_code == 0x06                    # target port not found, as before
    finally:
        other.close()


def test_runtime_state_and_symbol_version_read_not_written(plc):
    assert plc.read(0xF100, 0, pyads.PLCTYPE_UINT) == pyads.ADSSTATE_RUN      # the fake cycle's task_state: run
    assert plc.read(0xF100, 2, pyads.PLCTYPE_UINT) == 0
    assert plc.read(0xF008, 0, pyads.PLCTYPE_BYTE) == Device.FIRST_SYMBOL_VERSION
    for group, offset, typ in ((0xF008, 0, pyads.PLCTYPE_BYTE), (0xF100, 0, pyads.PLCTYPE_UINT)):
        with pytest.raises(pyads.ADSError) as e:
            plc.write(group, offset, 1, typ)
        assert e.value.err_code == 0x704
    with pytest.raises(pyads.ADSError) as e:
        plc.read(0xF008, 1, pyads.PLCTYPE_BYTE)
    assert e.value.err_code == 0x703
    # subscriptions: test_ads_server.py (their first sample can reach AdsLib before it knows the handle)


@pytest.fixture(scope="module")
def maps(tmp_path_factory):
    """The shipped map, the same read again, one symbol less, and one comment changed."""
    d = tmp_path_factory.mktemp("maps")
    return [RegisterMap.from_yaml(MAP), RegisterMap.from_yaml(MAP), map_variant(d, drop="period_jitter_us"),
            map_variant(d, old="joint correction to add to q_r", new="joint correction for q_r")]


@pytest.fixture(scope="module")
def device(maps):
    image = ProcessImage(maps[0])
    yield Device(image)
    image.close()


@settings(max_examples=60, deadline=None)
@given(st.lists(st.integers(0, 3), min_size=1, max_size=12))
def test_symbol_version_changes_whenever_the_symbol_set_does_and_only_then(maps, device, picks):
    for k in picks:
        before, served = device.symbol_version, device.symbols.upload
        after = device.install(maps[k])
        assert after == device.symbol_version == device.view().read(0xF008, 0, 1)[1][0]
        assert (after != before) == (SymbolTable(maps[k]).upload != served), (k, before, after)


def test_symbol_version_starts_at_its_first_value_and_each_change_differs_from_the_last(maps):
    image = ProcessImage(maps[0])
    try:
        dev = Device(image)
        assert dev.symbol_version == Device.FIRST_SYMBOL_VERSION == Device(image).symbol_version
        seen = [dev.symbol_version]
        for k in range(300):                                # past one byte's range: it wraps, still changing
            seen.append(dev.install(maps[2 + k % 2]))
        assert all(a != b for a, b in pairwise(seen)) and all(0 <= v <= 255 for v in seen)
    finally:
        image.close()


def test_data_types_upload_by_name_and_counts(plc):
    info = bytes(plc.read(0xF00F, 0, ctypes.c_ubyte * 24, return_ctypes=True))
    n_sym, sym_len, n_types, types_len = struct.unpack_from("<4I", info)
    assert (n_sym, sym_len) == (len(TABLE.symbols), len(TABLE.upload))
    upload = bytes(plc.read(0xF00E, 0, ctypes.c_ubyte * types_len, return_ctypes=True))
    entries, pos = [], 0
    while pos < len(upload):
        entry, length = parse_datatype(upload[pos:])
        entries.append(entry)
        pos += length
    assert pos == len(upload) == types_len and len(entries) == n_types
    used = {s.type_name for s in TABLE.symbols}
    assert {e["name"] for e in entries} == used and len(entries) == len(used)      # each used type once
    for e in entries:
        assert (e["ads"], e["size"]) == BASE_TYPES[e["name"]]
        assert (e["type"], e["offs"], e["array_dim"], e["sub_items"], e["flags"], e["version"]) == ("", 0, 0, 0, 1, 1)
        raw = raw_read_write(plc, 0xF011, e["name"].lower().encode() + b"\0", 0xFFFF)     # by name, any case
        assert parse_datatype(raw)[0] == e
    for unknown in (b"LREAL\0", b"ST_NoSuchType\0", b""):     # not used by a symbol: not a type of this runtime
        with pytest.raises(pyads.ADSError) as err:
            raw_read_write(plc, 0xF011, unknown or b"\0", 0xFFFF)
        assert err.value.err_code == 0x710


def test_handle_by_name_long_read_is_the_runtimes_answer_and_4_bytes_the_handle(plc):
    raw = raw_read_write(plc, 0xF003, b"GVL_Comp.q1\0", 0xFFFF)
    handle, size, ads_type, n = struct.unpack_from("<IIIH", raw)
    assert (size, ads_type, raw[14: 14 + n + 1]) == (4, 4, b"REAL\0")
    short = raw_read_write(plc, 0xF003, b"GVL_Comp.q1\0", 4)
    assert len(short) == 4 and struct.unpack("<I", short)[0] not in (0, handle)       # a new handle
    plc.write_by_name("GVL_Comp.q1", 6.5)
    for h in (handle, struct.unpack("<I", short)[0]):
        assert plc.read_by_name("", pyads.PLCTYPE_REAL, handle=h) == 6.5
        plc.release_handle(h)
    raw = raw_read_write(plc, 0xF003, f"{TASKINFO_PREFIX}.CycleTimeExceeded".encode() + b"\0", 0xFFFF)
    h, size, ads_type, n = struct.unpack_from("<IIIH", raw)
    assert (size, ads_type, raw[14: 14 + n]) == (1, 33, b"BOOL")
    plc.release_handle(h)
