"""The ADS server against the real client: pyads (Beckhoff's AdsLib) in this process, the server in a
spawn child whose fake cycle publishes changing values (ads_child.py)."""

from __future__ import annotations

import ctypes
import struct
import threading
import time
from itertools import pairwise

import pyads
import pytest

from plc_link.ads import symbols_from_map
from plc_link.ads.symbols import TASKINFO_PREFIX
from plc_link.register_map import RegisterMap
from testlib.ads_child import MAP, fake_values
from testlib.pyads_callbacks import delete_notification

pytestmark = pytest.mark.realtime

NET_ID = "5.6.7.8.1.1"
RMAP = RegisterMap.from_yaml(MAP)
TO_PLC = [r.name for r in RMAP.registers if r.direction == "to_plc"]
SYMBOLS = {s.name: s for s in symbols_from_map(RMAP)}
TASK = f"{TASKINFO_PREFIX}."


def ads_error(fn, *args, **kw) -> int:
    with pytest.raises(pyads.ADSError) as e:
        fn(*args, **kw)
    return e.value.err_code


def test_read_and_write_by_name_and_by_handle(plc):
    first = plc.read_by_name("GVL_Comp.cycle_count")
    for _ in range(100_000):                     # a bound on tries, not on time
        if plc.read_by_name("GVL_Comp.cycle_count") > first:
            break
    else:
        pytest.fail("cycle_count never rose")
    plc.write_by_name("GVL_Comp.q1", 12.5)
    assert plc.read_by_name("GVL_Comp.q1") == 12.5
    assert plc.read_by_name("gvl_comp.Q1", pyads.PLCTYPE_REAL) == 12.5       # names ignore case
    handle = plc.get_handle("GVL_Comp.q3")
    plc.write_by_name("", -7.25, pyads.PLCTYPE_REAL, handle=handle)
    assert plc.read_by_name("", pyads.PLCTYPE_REAL, handle=handle) == -7.25
    plc.release_handle(handle)
    assert ads_error(plc.read_by_name, "", pyads.PLCTYPE_REAL, handle=handle) == 0x710
    q3 = SYMBOLS["GVL_Comp.q3"]
    assert plc.read(q3.group, q3.offset, pyads.PLCTYPE_REAL) == -7.25        # the same bytes in %MB


def test_mb_area_lays_over_the_modbus_words(plc):
    raw = bytes(plc.read(0x4020, 0, ctypes.c_ubyte * 1024, return_ctypes=True))
    codec = RMAP.codecs["to_plc"]
    words = list(struct.unpack("<512H", raw))[: codec.words]      # to_plc block first, little-endian words
    values = dict(zip(codec.names, codec.decode(words)))
    expected = fake_values(int(values["cycle_count"]))
    for name in expected:
        assert values[name] == pytest.approx(expected[name], rel=1e-6), name


def test_sum_read_of_a_list_by_name_is_one_cycle(plc):
    names = [f"GVL_Comp.{n}" for n in TO_PLC] + [n for n in SYMBOLS if n.startswith(TASK)]
    got = plc.read_list_by_name(names)
    cycle = got["GVL_Comp.cycle_count"]
    for name, value in fake_values(cycle).items():
        assert got[f"GVL_Comp.{name}"] == pytest.approx(value, rel=1e-6), name
    assert got[TASK + "CycleCount"] == cycle
    assert got[TASK + "CycleTime"] == 10_000                 # 1000 µs in 100 ns
    assert got[TASK + "LastExecTime"] == 1234
    assert got[TASK + "ExceedCounter"] == cycle // 100
    assert got[TASK + "CycleTimeExceeded"] is bool(cycle % 2)
    plc.write_list_by_name({"GVL_Comp.q4": 1.5, "GVL_Comp.q5": 2.5})      # sum write
    assert plc.read_list_by_name(["GVL_Comp.q4", "GVL_Comp.q5"]) == {"GVL_Comp.q4": 1.5, "GVL_Comp.q5": 2.5}


def test_unknown_symbol_is_0x710_and_the_connection_goes_on(plc):
    assert ads_error(plc.read_by_name, "GVL_Comp.NoSuchSymbol", pyads.PLCTYPE_INT) == 0x710
    assert ads_error(plc.get_handle, "GVL_Comp.NoSuchSymbol") == 0x710
    assert ads_error(plc.read_write, 0xF004, 0, pyads.PLCTYPE_REAL, "GVL_Comp.NoSuchSymbol", pyads.PLCTYPE_STRING) \
        == 0x710
    assert plc.read_by_name("GVL_Comp.wrench_fz") == 42.0
    assert plc.read_write(0xF004, 0, pyads.PLCTYPE_REAL, "GVL_Comp.wrench_fz", pyads.PLCTYPE_STRING) == 42.0


def test_refused_writes_change_nothing(plc):
    before = bytes(plc.read(0x4020, 0, ctypes.c_ubyte * 1024, return_ctypes=True))
    q2 = SYMBOLS["GVL_Comp.q2"]
    assert ads_error(plc.write_by_name, "GVL_Comp.correction_q1", 1.0, pyads.PLCTYPE_REAL) == 0x704
    assert ads_error(plc.write_by_name, TASK + "CycleCount", 1, pyads.PLCTYPE_UDINT) == 0x704
    assert ads_error(plc.write_by_name, "GVL_Comp.q2", 1, pyads.PLCTYPE_INT) == 0x705         # 2 of 4 bytes
    assert ads_error(plc.write, 0x4020, q2.offset, 1, pyads.PLCTYPE_INT) == 0x705             # half a REAL
    assert ads_error(plc.write, 0x4020, q2.offset + 2, 1, pyads.PLCTYPE_UDINT) == 0x705       # straddles two
    assert ads_error(plc.write, 0x4020, 0, 1, pyads.PLCTYPE_UINT) == 0x704                    # to_plc block
    assert ads_error(plc.write, 0x4020, 1024, 1, pyads.PLCTYPE_UINT) == 0x703
    assert ads_error(plc.write, 0x4021, 0, 1, pyads.PLCTYPE_UINT) == 0x702
    after = bytes(plc.read(0x4020, 0, ctypes.c_ubyte * 1024, return_ctypes=True))
    assert after[512:] == before[512:]                       # the PLC's block is as it was


def test_get_all_symbols_lists_the_register_map_and_the_task_info(plc):
    got = {s.name: s for s in plc.get_all_symbols()}
    assert set(got) == set(SYMBOLS)
    for name, s in SYMBOLS.items():
        assert (got[name].index_group, got[name].index_offset, got[name].symbol_type) == \
               (s.group, s.offset, s.type_name)
    assert got["GVL_Comp.wrench_fz"].read() == 42.0


def test_notifications_cyclic_and_on_change(plc):
    seen: dict[str, list] = {"cyclic": [], "change": [], "task": []}
    lock = threading.Lock()

    def collect(key, plc_type):
        def cb(notification, name):
            _handle, stamp, value = plc.parse_notification(notification, plc_type)
            with lock:
                seen[key].append((stamp, value))
        return cb

    handles = [
        plc.add_device_notification("GVL_Comp.cycle_count", pyads.NotificationAttrib(
            4, pyads.constants.ADSTRANS_SERVERCYCLE, 0, 0), collect("cyclic", pyads.PLCTYPE_UDINT)),
        plc.add_device_notification("GVL_Comp.correction_q1", pyads.NotificationAttrib(
            4, pyads.constants.ADSTRANS_SERVERONCHA, 0, 0), collect("change", pyads.PLCTYPE_REAL)),
        plc.add_device_notification(TASK + "CycleCount", pyads.NotificationAttrib(
            4, pyads.constants.ADSTRANS_SERVERCYCLE, 0, 0), collect("task", pyads.PLCTYPE_UDINT)),
    ]
    give_up = time.monotonic() + 30.0         # a guard against a hang, not a timing requirement
    while time.monotonic() < give_up:
        with lock:
            if len(seen["change"]) >= 4 and len(seen["cyclic"]) >= 20 and len(seen["task"]) >= 5:
                break
        time.sleep(0.05)
    for h in handles:
        delete_notification(plc, h)
    with lock:
        cyclic, change, task = list(seen["cyclic"]), list(seen["change"]), list(seen["task"])
    assert len(change) >= 4 and len(cyclic) >= 20 and len(task) >= 5
    counts = [v for _, v in cyclic]
    assert counts == sorted(set(counts))                 # one sample per cycle, in order
    values = [v for _, v in change]
    assert all(a != b for a, b in pairwise(values))          # on-change: every sample a change
    assert all(v == 0.5 * round(v / 0.5) for v in values)
    assert len(change) < len(cyclic)
    now = time.time()
    for stamp, _ in cyclic + change + task:             # FILETIME of the cycle's start, converted by pyads
        assert abs(stamp.timestamp() - now) < 300.0


def test_sum_read_write_gets_handles_one_result_each(plc):
    names = [b"GVL_Comp.q6", b"GVL_Comp.NoSuchSymbol"]
    req = b"".join(struct.pack("<IIII", 0xF003, 0, 4, len(n)) for n in names) + b"".join(names)
    raw = bytes(plc.read_write(0xF082, len(names), ctypes.c_ubyte * 28, list(req), ctypes.c_ubyte * len(req),
                               return_ctypes=True, check_length=False))
    (err1, len1), (err2, len2) = struct.unpack_from("<II", raw, 0), struct.unpack_from("<II", raw, 8)
    assert (err1, len1, err2, len2) == (0, 4, 0x710, 0)
    handle = struct.unpack_from("<I", raw, 16)[0]
    plc.write_by_name("GVL_Comp.q6", 3.75)
    assert plc.read_by_name("", pyads.PLCTYPE_REAL, handle=handle) == 3.75
    plc.release_handle(handle)


def test_device_info_and_state(plc):
    name, version = plc.read_device_info()
    assert name == "stiffcomp" and (version.version, version.revision) == (0, 1)
    assert plc.read_state() == (pyads.ADSSTATE_RUN, 0)          # the fake cycle's task_state is 1 (run)
