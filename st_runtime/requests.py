"""The request blocks of Beckhoff's libraries, with their manuals' pins and timing: ADSREAD and ADSWRITE
(Tc2_System), FB_MBReadRegs, FB_MBReadInputRegs and FB_MBWriteRegs (TF6250 Modbus TCP, Tc2_ModbusSrv).

The time model, as the manuals describe the blocks (Beckhoff Information System, Tc2_System ADSREAD; TF6250
FB_MBReadRegs): a rising edge of the execute pin starts one request and sets the busy pin; the block ends it
(busy FALSE, then the error pin and id) at a later call, never in the call that started it, when the answer
has come or the timeout has passed, whichever is first. A request that times out moves no data: a read copies
nothing into its buffer, and a write the network has not yet delivered is cancelled.

The requests travel over the runtime's `Network` (`Runtime.network`), which the caller provides: the HIL's
virtual PLC a real Modbus TCP client of the service, a test a simulated one. ``start`` returns a `Transfer`,
which says when it has ended and with what.

Error ids (``nErrId``, ``ERRID``): the ADS return codes (Beckhoff, "ADS Return Codes": 0x745
ADSERR_CLIENT_SYNCTIMEOUT for a timeout, 0x705 ADSERR_DEVICE_INVALIDSIZE for a buffer too small) and TF6250's
own (Beckhoff, TF6250 "Return codes": 0x8001 Modbus function not implemented, 0x8002 invalid address or
length, 0x8003 invalid parameters: wrong number of registers, 0x8004 Modbus server error); a Modbus exception
code 1-3 maps to 0x8000 + the code, any other to 0x8004. TF6250's ``cbLength`` is the size of the buffer
``pDestAddr`` or ``pSrcAddr`` points to, a maximum: a request is refused only when its registers do not fit.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any, Protocol

from .blocks import Block
from .values import POINTER, Str

TIMEOUT = 0x745                 # ADSERR_CLIENT_SYNCTIMEOUT (ADS return codes)
INVALID_SIZE = 0x705            # ADSERR_DEVICE_INVALIDSIZE: the buffer is too small for the data
MB_FUNCTION, MB_ADDRESS, MB_PARAMETER, MB_SERVER = 0x8001, 0x8002, 0x8003, 0x8004     # TF6250 return codes
WIN32 = 0x80070000              # TF6250: a Win32 (socket) error code, plus this


def modbus_error(exception_code: int) -> int:
    """TF6250's nErrId for a Modbus exception response with ``exception_code``."""
    return 0x8000 + exception_code if exception_code in (1, 2, 3) else MB_SERVER


@dataclass(frozen=True)
class Ended:
    """How a request ended: its error id (0: none), the data a read brought, and when (runtime ms)."""

    error: int
    data: bytes = b""
    at_ms: int = 0


class Transfer(Protocol):
    def ended(self, now_ms: int) -> Ended | None:
        """How the request ended by ``now_ms``; None while it runs."""

    def cancel(self) -> None:
        """The block gave up on it (its timeout): a write not yet delivered is not delivered."""


class Network(Protocol):
    """Where the requests go. Each call starts one request at ``now_ms`` and returns its `Transfer`."""

    def modbus_read(self, host: str, port: int, unit: int, table: str, address: int, count: int,
                    now_ms: int) -> Transfer: ...

    def modbus_write(self, host: str, port: int, unit: int, address: int, words: list[int],
                     now_ms: int) -> Transfer: ...

    def ads_read(self, net_id: str, port: int, group: int, offset: int, length: int, now_ms: int) -> Transfer: ...

    def ads_write(self, net_id: str, port: int, group: int, offset: int, data: bytes, now_ms: int) -> Transfer: ...


class Refused:
    """A request the block refuses before sending it (its parameters): it ends at the next call."""

    def __init__(self, error: int, now_ms: int):
        self.result = Ended(error, b"", now_ms)

    def ended(self, now_ms: int) -> Ended:
        return self.result

    def cancel(self) -> None:
        pass


class Request(Block):
    """A request block (`PINS`: execute, busy, error, error id and timeout pins' names)."""

    PINS = ("", "", "", "", "")

    def body(self) -> None:
        now = self._m.runtime.now_ms
        execute_pin, busy, error_pin, error_id, timeout_pin = self.PINS
        execute = getattr(self, execute_pin)
        transfer = getattr(self, "_transfer", None)
        if transfer is not None:
            ended = transfer.ended(now)
            late = now - self._started >= getattr(self, timeout_pin)
            if ended is not None and ended.at_ms - self._started <= getattr(self, timeout_pin):
                if ended.error == 0:
                    self.deliver(ended.data)
                self._end(ended.error)
            elif late:
                transfer.cancel()
                self._end(TIMEOUT)
        elif execute and not getattr(self, "_last", False):
            self._started = now
            self._transfer = self.start(self._m.runtime.network, now)
            setattr(self, busy, True)
            setattr(self, error_pin, False)
            setattr(self, error_id, 0)
        self._last = execute

    def _end(self, error: int) -> None:
        _, busy, error_pin, error_id, _ = self.PINS
        setattr(self, busy, False)
        setattr(self, error_pin, error != 0)
        setattr(self, error_id, error)
        self._transfer = None

    def start(self, net: Network, now: int) -> Transfer:
        raise NotImplementedError

    def deliver(self, data: bytes) -> None:
        """A read's data into its buffer (a write has none)."""


_ADS_IN = {"NETID": Str(23), "PORT": "UINT", "IDXGRP": "UDINT", "IDXOFFS": "UDINT", "LEN": "UDINT", "TMOUT": "TIME"}
_ADS_OUT = {"BUSY": "BOOL", "ERR": "BOOL", "ERRID": "UDINT"}


class ADSREAD(Request):
    INPUTS, OUTPUTS = {**_ADS_IN, "DESTADDR": POINTER, "READ": "BOOL"}, _ADS_OUT
    PINS = ("READ", "BUSY", "ERR", "ERRID", "TMOUT")

    def start(self, net: Network, now: int) -> Transfer:
        return net.ads_read(self.NETID, self.PORT, self.IDXGRP, self.IDXOFFS, self.LEN, now)

    def deliver(self, data: bytes) -> None:
        self.DESTADDR.write(data[:self.LEN], self._m)


class ADSWRITE(Request):
    INPUTS, OUTPUTS = {**_ADS_IN, "SRCADDR": POINTER, "WRITE": "BOOL"}, _ADS_OUT
    PINS = ("WRITE", "BUSY", "ERR", "ERRID", "TMOUT")

    def start(self, net: Network, now: int) -> Transfer:
        return net.ads_write(self.NETID, self.PORT, self.IDXGRP, self.IDXOFFS, self.SRCADDR.read(self.LEN, self._m),
                             now)


_MB_IN = {"sIPAddr": Str(15), "nTCPPort": "UINT", "nUnitID": "BYTE", "nQuantity": "WORD", "nMBAddr": "WORD",
          "cbLength": "UDINT", "bExecute": "BOOL", "tTimeout": "TIME"}
_MB_OUT = {"bBusy": "BOOL", "bError": "BOOL", "nErrId": "UDINT", "cbRead": "UDINT"}
_MB_PINS = ("bExecute", "bBusy", "bError", "nErrId", "tTimeout")


class _MbRead(Request):
    INPUTS, OUTPUTS = {**_MB_IN, "pDestAddr": POINTER}, _MB_OUT
    PINS = _MB_PINS
    TABLE = ""

    def start(self, net: Network, now: int) -> Transfer:
        self.cbRead = 0
        if 2 * self.nQuantity > self.cbLength:
            return Refused(INVALID_SIZE, now)
        return net.modbus_read(self.sIPAddr, self.nTCPPort, self.nUnitID, self.TABLE, self.nMBAddr, self.nQuantity,
                               now)

    def deliver(self, data: bytes) -> None:
        self.pDestAddr.write(data, self._m)
        self.cbRead = len(data)


class FB_MBReadRegs(_MbRead):
    TABLE = "holding_registers"


class FB_MBReadInputRegs(_MbRead):
    TABLE = "input_registers"


class FB_MBWriteRegs(Request):
    INPUTS, OUTPUTS = {**_MB_IN, "pSrcAddr": POINTER}, {k: v for k, v in _MB_OUT.items() if k != "cbRead"}
    PINS = _MB_PINS

    def start(self, net: Network, now: int) -> Transfer:
        if 2 * self.nQuantity > self.cbLength:
            return Refused(INVALID_SIZE, now)
        data = self.pSrcAddr.read(2 * self.nQuantity, self._m)
        words = list(struct.unpack(f"<{self.nQuantity}H", data))
        return net.modbus_write(self.sIPAddr, self.nTCPPort, self.nUnitID, self.nMBAddr, words, now)


REQUESTS: dict[str, Any] = {c.__name__: c for c in (ADSREAD, ADSWRITE, FB_MBReadRegs, FB_MBReadInputRegs,
                                                    FB_MBWriteRegs)}
