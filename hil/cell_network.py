"""The cell's network between the virtual PLC's program and the service: the `st_runtime.Network` the program's
request blocks send their requests over (TF6250's FB_MBReadInputRegs, FB_MBReadRegs and FB_MBWriteRegs; Tc2_System's
ADSREAD and ADSWRITE), with the HIL's transport faults on it.

* `TcpNetwork`, in real time: a pymodbus TCP client of the service's Modbus server and an AMS/TCP client of its
  ADS server (`hil.ads_client`). Each request is sent when the block starts it and its answer awaited there
  (well under a millisecond on one host); the block takes it at its next call, as a real block ends at a later
  cycle than the one that started it. A request whose answer took longer than the block's timeout ends as timed
  out (`st_runtime.requests`).
* `ImageNetwork`, in lock step: the same requests served by the service's process image in the same process
  (`ProcessImage.read`, `ProcessImage.write`: the Modbus server's rules; `ads.area`: the ADS server's %MB area).

The program dials the address its settings name (``GVL_StiffCompSettings.sModbusHost`` and ``nModbusPort``, or
``sAmsNetId`` and ``nAmsPort``): the HIL's network routes it to the HIL's service, as a cell's network (or its
ADS routes) takes it to the IPC the service runs on, and records what was dialled (`dialled`) for the summary.

Faults (`PlcFaults`) act on the transport, not on the program: the connection drops for a while (every request
fails as a refused connection does, Win32 WSAECONNREFUSED 10061 in TF6250's 0x8007xxxx range); the PLC's
heartbeat word freezes in the Modbus writes that carry it (a gateway that stops updating it; an ADS program's
heartbeat is not frozen); and ``delay_ms``, a slower fieldbus, hands each read the service's answer as it was
that long before.
"""

from __future__ import annotations

import math
import struct
import time
from collections import deque
from dataclasses import dataclass

from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

from plc_link.ads import ams
from plc_link.ads.area import MB_GROUP, AreaView, Layout
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from st_runtime import Ended
from st_runtime.requests import MB_ADDRESS, WIN32, modbus_error

from .ads_client import AdsClient

REFUSED = WIN32 + 10061              # WSAECONNREFUSED
RECONNECT_MS = 50                    # at most one connection attempt this often


@dataclass
class PlcFaults:
    """Faults to inject (times in s of the PLC's program time; None = never)."""

    heartbeat_stop_at: float | None = None
    drop_at: float | None = None
    drop_for_s: float = 0.0


class Done:
    """A request that ended when it was served (``at_ms``); the block takes it at its next call."""

    def __init__(self, error: int, data: bytes, at_ms: int):
        self.result = Ended(error, data, at_ms)

    def ended(self, now_ms: int) -> Ended:
        return self.result

    def cancel(self) -> None:
        pass


class DelayedRead:
    """A read through a slower fieldbus: it brings the answer the service gave ``delay_ms`` before the request
    was sent (before the line has filled, the oldest), so its data are that much older than a direct read's."""

    def __init__(self, net: CellNetwork, sent_ms: int, at_ms: int):
        self.net, self.sent_ms, self.at_ms = net, sent_ms, at_ms

    def ended(self, now_ms: int) -> Ended:
        answers = self.net.answers
        old = [data for t, data in answers if t <= self.sent_ms - self.net.delay_ms]
        return Ended(0, old[-1] if old else answers[0][1], self.at_ms)

    def cancel(self) -> None:
        pass


class CellNetwork:
    """The transport and its faults; `_read` and `_write` are the server's side (`TcpNetwork`, `ImageNetwork`).

    Parameters
    ----------
    rmap : the service's register map (where the PLC's heartbeat word is)
    faults : PlcFaults
    delay_ms : the slower fieldbus's delay (the scenario's ``plc.extra_delay_ms``)
    """

    def __init__(self, rmap: RegisterMap, faults: PlcFaults | None = None, delay_ms: float = 0.0):
        self.faults = faults or PlcFaults()
        self.delay_ms = float(delay_ms)
        self.heartbeat_address = rmap.by_name["plc_heartbeat"].address
        self.frozen: int | None = None
        self.answers: deque[tuple[int, bytes]] = deque(maxlen=256)
        self.dialled: set[str] = set()             # "Modbus host:port unit n", "ADS net-id port n"
        self.written: set[int] = set()            # every address the program wrote
        self.errors = 0

    def dropped(self, now_ms: int) -> bool:
        f = self.faults
        return f.drop_at is not None and f.drop_at <= now_ms / 1000.0 < f.drop_at + f.drop_for_s

    def modbus_read(self, host, port, unit, table, address, count, now_ms):
        self.dialled.add(f"Modbus {host}:{port} unit {unit}")
        error, words, at = self._request(now_ms, lambda: self._read(table, address, count))
        return self._answer(error, b"" if error else struct.pack(f"<{count}H", *words), now_ms, at)

    def modbus_write(self, host, port, unit, address, words, now_ms):
        self.dialled.add(f"Modbus {host}:{port} unit {unit}")
        words = list(words)
        k = self.heartbeat_address - address
        if 0 <= k < len(words):
            stop = self.faults.heartbeat_stop_at
            if stop is not None and now_ms / 1000.0 >= stop:
                self.frozen = words[k] if self.frozen is None else self.frozen
                words[k] = self.frozen
        error, _, at = self._request(now_ms, lambda: self._write(address, words))
        if not error:
            self.written.update(range(address, address + len(words)))
        return Done(error, b"", at)

    def ads_read(self, net_id, port, group, offset, length, now_ms):
        self.dialled.add(f"ADS {net_id} port {port}")
        error, data, at = self._request(now_ms, lambda: self._ads_read(str(net_id), int(port), group, offset, length))
        return self._answer(error, data or b"", now_ms, at)

    def ads_write(self, net_id, port, group, offset, data, now_ms):
        self.dialled.add(f"ADS {net_id} port {port}")
        error, _, at = self._request(now_ms, lambda: self._ads_write(str(net_id), int(port), group, offset, data))
        return Done(error, b"", at)

    def _answer(self, error: int, data: bytes, sent_ms: int, at_ms: int):
        """A read's transfer: its answer as it came, or through the slower fieldbus (`DelayedRead`)."""
        if error or self.delay_ms <= 0:
            return Done(error, data, at_ms)
        self.answers.append((sent_ms, data))
        return DelayedRead(self, sent_ms, at_ms)

    def _request(self, now_ms: int, call) -> tuple[int, list[int] | None, int]:
        """(error id, the words, when it ended in ms) of one request."""
        if self.dropped(now_ms):
            self.close()
            self.errors += 1
            return REFUSED, None, now_ms
        error, words, took_ms = call()
        self.errors += bool(error)
        return error, words, now_ms + took_ms

    def _read(self, table: str, address: int, count: int) -> tuple[int, list[int] | None, int]:
        raise NotImplementedError

    def _write(self, address: int, words: list[int]) -> tuple[int, None, int]:
        raise NotImplementedError

    def _ads_read(self, net_id: str, port: int, group: int, offset: int, length: int) -> tuple[int, bytes, int]:
        raise NotImplementedError

    def _ads_write(self, net_id: str, port: int, group: int, offset: int, data: bytes) -> tuple[int, None, int]:
        raise NotImplementedError

    def close(self) -> None:
        """Drop the connection (a fault); the next request after the fault reconnects."""


class ImageNetwork(CellNetwork):
    """Lock step: the service's process image answers in the same process, at once."""

    def __init__(self, image: ProcessImage, rmap: RegisterMap, faults: PlcFaults | None = None,
                 delay_ms: float = 0.0):
        super().__init__(rmap, faults, delay_ms)
        self.image = image
        self.layout = Layout(rmap)

    def _read(self, table, address, count):
        words = self.image.read(table, address, count)
        return (MB_ADDRESS, None, 0) if words is None else (0, list(words), 0)

    def _write(self, address, words):
        return (0 if self.image.write("holding_registers", address, words) else MB_ADDRESS), None, 0

    def _ads_read(self, net_id, port, group, offset, length):
        error, data = AreaView(self.layout, self.image.snapshot()).read(group, offset, length)
        return error, data, 0

    def _ads_write(self, net_id, port, group, offset, data):
        error = self.layout.write(self.image, offset, data) if group == MB_GROUP else ams.ADSERR_INVALID_GROUP
        return error, None, 0


class TcpNetwork(CellNetwork):
    """Real time: a Modbus TCP client of the service at ``host``:``port`` (pymodbus) and an ADS client of it at
    ``host``:``ads_port``; ``timeout_s`` bounds one request's wait (the program's own timeout decides whether it
    was late)."""

    def __init__(self, host: str, port: int, rmap: RegisterMap, faults: PlcFaults | None = None,
                 delay_ms: float = 0.0, timeout_s: float = 0.1, clock=time.monotonic, ads_port: int | None = None):
        super().__init__(rmap, faults, delay_ms)
        self.client = ModbusTcpClient(host, port=port, timeout=timeout_s, retries=0)
        self.ads = AdsClient(host, ads_port, timeout_s=timeout_s) if ads_port else None
        self.clock = clock
        self.connected = False
        self.next_attempt = -math.inf

    def connect(self, deadline: float) -> bool:
        """Try to connect until ``deadline`` (clock time); True when connected."""
        while self.clock() < deadline:
            if self.client.connect() and (self.ads is None or self.ads.connect()):
                self.connected = True
                return True
            time.sleep(0.05)
        return False

    def close(self) -> None:
        self.client.close()
        if self.ads is not None:
            self.ads.close()
        self.connected = False

    def _call(self, send) -> tuple[int, list[int] | bytes | None, int]:
        """(error id, what ``send`` brought, ms it took): ``send`` returns (error id, payload)."""
        start = self.clock()
        if not self.connected and start >= self.next_attempt:
            self.next_attempt = start + RECONNECT_MS / 1000.0
            self.connected = bool(self.client.connect()) and (self.ads is None or self.ads.connect())
        if not self.connected:
            return REFUSED, None, 0
        try:
            error, payload = send()
        except (ModbusException, OSError):
            self.close()
            error, payload = REFUSED, None
        return error, payload, math.ceil((self.clock() - start) * 1000.0)

    @staticmethod
    def _modbus(r) -> tuple[int, list[int] | None]:
        """(TF6250's error id, the registers) of a pymodbus response."""
        if r.isError():
            return modbus_error(int(getattr(r, "exception_code", 4))), None
        return 0, list(getattr(r, "registers", []))

    def _read(self, table, address, count):
        fn = self.client.read_input_registers if table == "input_registers" else self.client.read_holding_registers
        return self._call(lambda: self._modbus(fn(address, count=count)))

    def _write(self, address, words):
        error, _, took = self._call(lambda: self._modbus(self.client.write_registers(address, words)))
        return error, None, took

    def _ads_read(self, net_id, port, group, offset, length):
        if self.ads is None:
            return ams.ERR_TARGET_MACHINE_NOT_FOUND, None, 0
        return self._call(lambda: self.ads.read(net_id, port, group, offset, length))

    def _ads_write(self, net_id, port, group, offset, data):
        if self.ads is None:
            return ams.ERR_TARGET_MACHINE_NOT_FOUND, None, 0
        error, _, took = self._call(lambda: (self.ads.write(net_id, port, group, offset, data), None))
        return error, None, took
