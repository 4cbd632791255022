"""The Modbus TCP client role: the service writes into the PLC's registers and reads the PLC's.

Every ``period_s`` the thread writes the whole ``to_plc`` block into the PLC's holding registers at
``write_start`` with one FC16 request, and reads the ``from_plc`` block from ``read_table`` at
``read_start`` with one FC4 (or FC3) request. The defaults follow a TF6250 server on the PLC: the
service writes the PLC memory area (%MW, holding registers 0x3000..) and reads what the PLC program
puts in GVL.mb_Input_Registers (input registers 0x8000..). Registers keep their offsets within
each block. The cycle thread never waits for the network: it only touches the `RegisterImage`. If the
PLC stops answering, the inputs stop changing, so the PLC heartbeat fault trips in the cycle.
"""

from __future__ import annotations

import logging
import threading
import time

from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

from .errors import PlcConnectionError
from .image import RegisterImage

log = logging.getLogger("stiffcomp.modbus")


class ModbusClientThread:
    """Exchange the register image with a PLC acting as Modbus TCP server.

    Parameters
    ----------
    image : RegisterImage
    host, port, device_id : the PLC
    period_s : exchange period
    timeout_s : per-request timeout
    write_start : first holding register the to_plc block is written to
    read_table, read_start : where the from_plc block is read from
    """

    def __init__(self, image: RegisterImage, host: str, port: int, device_id: int = 1, period_s: float = 0.01,
                 timeout_s: float = 1.0, write_start: int = 0x3000, read_table: str = "input_registers",
                 read_start: int = 0x8000):
        self.image = image
        self.host, self.port, self.device_id = host, port, device_id
        self.period = period_s
        self.client = ModbusTcpClient(host, port=port, timeout=timeout_s, retries=0)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="stiffcomp-modbus-client", daemon=True)
        self.exchanges = 0
        self.errors = 0
        self._out_start, self._out_words = write_start, image.out_codec.words
        self._in_start, self._in_words = read_start, image.in_codec.words
        self._read = (self.client.read_input_registers if read_table == "input_registers"
                      else self.client.read_holding_registers)

    def start(self) -> None:
        if not self.client.connect():
            self.client.close()
            raise PlcConnectionError(f"cannot connect to the PLC at {self.host}:{self.port} (Modbus TCP)")
        self._thread.start()
        log.info("Modbus TCP client to the PLC at %s:%d, every %.0f ms", self.host, self.port, self.period * 1e3)

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(5.0)
        try:
            self.exchange()                 # the final state (stopped, zero correction) reaches the PLC
        except (ModbusException, OSError, PlcConnectionError):
            pass
        self.client.close()

    def exchange(self) -> None:
        """Write the to_plc block, read the from_plc block (one request each)."""
        block = self.image.blocks["to_plc"][2]
        with self.image.lock:
            words = block[: self._out_words]
        r = self.client.write_registers(self._out_start, words, device_id=self.device_id)
        if r.isError():
            raise PlcConnectionError(f"the PLC refused the write at {self._out_start:#06x}: {r}")
        r = self._read(self._in_start, count=self._in_words, device_id=self.device_id)
        if r.isError():
            raise PlcConnectionError(f"the PLC refused the read at {self._in_start:#06x}: {r}")
        inputs = self.image.blocks["from_plc"][2]
        with self.image.lock:
            inputs[: self._in_words] = r.registers
        self.exchanges += 1

    def _run(self) -> None:
        due = time.monotonic()
        while not self._stop.is_set():
            try:
                self.exchange()
            except (ModbusException, OSError, PlcConnectionError) as e:
                self.errors += 1
                if self.errors == 1 or self.errors % 100 == 0:
                    log.error("exchange with the PLC failed (%d so far): %s", self.errors, e)
            due += self.period
            self._stop.wait(max(0.0, due - time.monotonic()))
