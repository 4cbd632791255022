"""The Modbus TCP client role: the service writes into the PLC's registers and reads the PLC's.

Every ``period_s`` (on `Deadlines`) the I/O loop writes the mapped ``to_plc`` words into the PLC's
holding registers at ``write_start`` with one FC16 request, and reads the ``from_plc`` block from
``read_table`` at ``read_start`` with one FC4 (or FC3) request. The defaults follow a TF6250 server on
the PLC: the service writes the PLC memory area (%MW, holding registers 0x3000..) and reads what the
PLC program puts in GVL.mb_Input_Registers (input registers 0x8000..). Registers keep their offsets
within each block. The cycle never waits for the network: it only touches the `ProcessImage`. If the
PLC stops answering, the inputs stop changing, so the PLC heartbeat fault trips in the cycle.
"""

from __future__ import annotations

import asyncio
import logging

from pymodbus.client import AsyncModbusTcpClient
from pymodbus.exceptions import ModbusException

from io_base.deadlines import Deadlines, cancel
from io_base.ratelog import RateLimitedLog

from .errors import PlcConnectionError
from .image import ProcessImage

log = logging.getLogger("stiffcomp.modbus")


class ModbusClient:
    """Exchange the process image with a PLC acting as Modbus TCP server, on the running asyncio loop.

    Parameters
    ----------
    image : ProcessImage
    host, port, device_id : the PLC
    period_s : exchange period
    timeout_s : per-request timeout
    write_start : first holding register the to_plc block is written to
    read_table, read_start : where the from_plc block is read from
    """

    def __init__(self, image: ProcessImage, host: str, port: int, device_id: int = 1, period_s: float = 0.01,
                 timeout_s: float = 1.0, write_start: int = 0x3000, read_table: str = "input_registers",
                 read_start: int = 0x8000):
        self.image = image
        self.host, self.port, self.device_id = host, port, device_id
        self.period = period_s
        self.timeout = timeout_s
        self.client = AsyncModbusTcpClient(host, port=port, timeout=timeout_s, retries=0)
        self.errors = RateLimitedLog(log)
        self._out_start, self._in_start = write_start, read_start
        self._in_words = image.in_codec.words
        self._read_fc4 = read_table == "input_registers"
        self._task: asyncio.Task | None = None
        self._stopping = False
        self.final_write_failed = False

    async def start(self) -> None:
        if not await self.client.connect():
            self.client.close()
            raise PlcConnectionError(f"cannot connect to the PLC at {self.host}:{self.port} (Modbus TCP)")
        self._task = asyncio.get_running_loop().create_task(self._run())
        log.info("Modbus TCP client to the PLC at %s:%d, every %.0f ms", self.host, self.port, self.period * 1e3)

    async def stop(self) -> None:
        """End the periodic exchange after the one in flight, then write the final state once.

        The exchange in flight is let finish, not cancelled: a cancelled request's reply is still
        owed, and a final write sent behind it makes two requests at once. A PLC's server may take
        one at a time; pymodbus' own server drops what it has received when more than 264 bytes
        wait (two of our writes), and the PLC then never sees the stopped state. Only an exchange
        still running after both its requests' timeouts is cancelled."""
        self._stopping = True
        if self._task is not None:
            await asyncio.wait((self._task,), timeout=2 * self.timeout + self.period)
        await cancel(self._task)
        try:
            await self.exchange()            # the final state (stopped, zero correction) reaches the PLC
        except (ModbusException, OSError, PlcConnectionError) as e:
            self.final_write_failed = True
            log.warning("the stopped state may not have reached the PLC at %s:%d (%s); its heartbeat "
                        "watch sees the service stop", self.host, self.port, e)
        self.client.close()

    async def exchange(self) -> None:
        """Write the to_plc block, read the from_plc block (one request each)."""
        r = await self.client.write_registers(self._out_start, self.image.to_plc_words(), device_id=self.device_id)
        if r.isError():
            raise PlcConnectionError(f"the PLC refused the write at {self._out_start:#06x}: {r}")
        read = self.client.read_input_registers if self._read_fc4 else self.client.read_holding_registers
        r = await read(self._in_start, count=self._in_words, device_id=self.device_id)
        if r.isError():
            raise PlcConnectionError(f"the PLC refused the read at {self._in_start:#06x}: {r}")
        self.image.write_block(r.registers)

    async def _run(self) -> None:
        deadlines = Deadlines(self.period)
        while not self._stopping:
            try:
                await self.exchange()
            except (ModbusException, OSError, PlcConnectionError) as e:
                self.errors.report(f"PLC {self.host}:{self.port}", "exchange failed", str(e))
            deadlines.advance(deadlines.clock())
            await deadlines.wait_async()
