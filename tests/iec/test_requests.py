"""Beckhoff's request blocks in the runtime (`st_runtime.requests`): a request ends at its timeout, never in the
call that starts it, moves no data when it times out, and reports TF6250's error ids; ``cbLength`` is the
buffer's size, a maximum. Each on a small MAIN calling FB_MBReadRegs and FB_MBWriteRegs over a network whose
requests take as long as the test says."""

from __future__ import annotations

import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cell.plc.model import BOOL, UDINT, Derived, Elementary, Pou, Struct, Var, VarList
from cell.plc.twincat import object_file
from st_runtime import Ended, Runtime, load
from st_runtime.requests import INVALID_SIZE, MB_ADDRESS, MB_SERVER, TIMEOUT, modbus_error

WORD = Elementary("WORD")
BODY = """\
fbRead(sIPAddr := '127.0.0.1', nTCPPort := 502, nUnitID := 1, nQuantity := 2, nMBAddr := 16#10,
       cbLength := nReadLength, pDestAddr := ADR(aIn), tTimeout := T#100MS, bExecute := bRead);
fbWrite(sIPAddr := '127.0.0.1', nTCPPort := 502, nUnitID := 1, nQuantity := 2, nMBAddr := 16#20,
        cbLength := 4, pSrcAddr := ADR(aOut), tTimeout := T#100MS, bExecute := bWrite);
"""
LOCAL = (Var("fbRead", Derived("FB_MBReadRegs")), Var("fbWrite", Derived("FB_MBWriteRegs")),
         Var("aIn", Derived("ST_Two")), Var("aOut", Derived("ST_Two")), Var("bRead", BOOL),
         Var("bWrite", BOOL), Var("nReadLength", UDINT, "4"))


class Transfer:
    def __init__(self, net, serve, now: int):
        self.net, self.serve, self.due = net, serve, now + net.took

    def ended(self, now: int):
        if self.serve is not None and now >= self.due:
            error, data = self.serve()
            self.serve = None
            self.result = Ended(error, data, self.due)
        return getattr(self, "result", None)

    def cancel(self) -> None:
        self.serve = None


class Net:
    """Registers 0x10.. hold ``words``; writes land in ``written``; every request takes ``took`` ms and answers
    with the Modbus exception ``exception`` when set."""

    def __init__(self, took: int = 5, exception: int = 0):
        self.took, self.exception, self.written, self.sent = took, exception, [], 0

    def modbus_read(self, host, port, unit, table, address, count, now_ms):
        self.sent += 1
        if self.exception:
            return Transfer(self, lambda: (modbus_error(self.exception), b""), now_ms)
        return Transfer(self, lambda: (0, struct.pack("<2H", 0x1234, 0xBEEF)), now_ms)

    def modbus_write(self, host, port, unit, address, words, now_ms):
        self.sent += 1
        return Transfer(self, lambda: (self.written.append(list(words)), (0, b""))[1], now_ms)


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("req")
    out = []
    for obj in (Struct("ST_Two", (Var("a", WORD), Var("b", WORD)), pack=True),
                Pou("MAIN", "PROGRAM", (VarList("VAR", LOCAL),), BODY)):
        name, data = object_file(obj)
        (folder / name).write_bytes(data)
        out.append(folder / name)
    return out


def main_on(files, net) -> tuple[Runtime, object]:
    runtime = Runtime(net)
    return runtime, load(files, runtime).instance("MAIN")


def run(runtime, main, ms: int, **pins) -> list[tuple[int, bool, bool, int]]:
    """Call MAIN every ms for ``ms`` ms with ``pins`` held: (now, busy, error, error id) of the read each ms."""
    out = []
    for _ in range(ms):
        for k, v in pins.items():
            setattr(main, k, v)
        main.body()
        out.append((runtime.now_ms, main.fbRead.bBusy, main.fbRead.bError, main.fbRead.nErrId))
        runtime.now_ms += 1
    return out


@given(st.integers(101, 400))
@settings(max_examples=15, deadline=None)
def test_a_request_longer_than_its_timeout_ends_at_the_timeout_with_no_data(files, took):
    runtime, main = main_on(files, Net(took))
    seen = run(runtime, main, 200, bRead=True, bWrite=True)
    ended = next(s for s in seen if not s[1])
    assert ended == (100, False, True, TIMEOUT)                     # T#100MS after the start, not took / 2
    assert (main.aIn.a, main.aIn.b) == (0, 0) and main.fbRead.cbRead == 0           # a timed-out read copies nothing
    assert main.fbWrite.bError and main.fbWrite.nErrId == TIMEOUT
    run(runtime, main, took + 10, bRead=False, bWrite=False)        # the network's time passes
    assert runtime.network.written == []                            # ... and the write never lands


@given(st.integers(0, 99))
@settings(max_examples=15, deadline=None)
def test_a_request_within_its_timeout_ends_when_its_answer_comes_never_in_the_starting_call(files, took):
    runtime, main = main_on(files, Net(took))
    seen = run(runtime, main, 150, bRead=True, bWrite=True)
    assert seen[0][1] is True                                       # busy after the call that started it
    end = next(s for s in seen if not s[1])[0]
    assert end == max(took, 1)
    assert (main.aIn.a, main.aIn.b) == (0x1234, 0xBEEF) and main.fbRead.cbRead == 4 and not main.fbRead.bError
    assert runtime.network.written == [[0, 0]]


@pytest.mark.parametrize(("exception", "err"), [(1, 0x8001), (2, MB_ADDRESS), (3, 0x8003), (4, MB_SERVER),
                                                 (6, MB_SERVER), (11, MB_SERVER)])
def test_a_modbus_exception_is_tf6250s_error_id(files, exception, err):
    runtime, main = main_on(files, Net(5, exception))
    seen = run(runtime, main, 10, bRead=True)
    assert (False, True, err) in {s[1:] for s in seen}
    assert (main.aIn.a, main.aIn.b) == (0, 0)


@pytest.mark.parametrize("length", [4, 5, 64])
def test_cblength_is_the_buffers_size_a_maximum(files, length):
    runtime, main = main_on(files, Net(2))
    run(runtime, main, 10, bRead=True, nReadLength=length)
    assert not main.fbRead.bError and (main.aIn.a, main.aIn.b) == (0x1234, 0xBEEF) and main.fbRead.cbRead == 4


def test_a_buffer_too_small_is_refused_without_a_request(files):
    runtime, main = main_on(files, Net(2))
    run(runtime, main, 10, bRead=True, nReadLength=3)
    assert main.fbRead.bError and main.fbRead.nErrId == INVALID_SIZE and runtime.network.sent == 0
