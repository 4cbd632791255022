"""The to_plc block of a running service over Modbus TCP, decoded by register name: `stiffcomp status`
reads it for its view, `stiffcomp health` where the service serves no HTTP."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ModbusException

if TYPE_CHECKING:
    from plc_interface.register_map import RegisterMap


class BlockReader:
    """The to_plc block over Modbus, decoded into values by register name."""

    def __init__(self, rmap: RegisterMap, host: str, port: int, timeout_s: float = 0.5):
        block = rmap.blocks["to_plc"]
        self.codec = rmap.codecs["to_plc"]
        self.client = ModbusTcpClient(host, port=port, timeout=timeout_s, retries=0)
        self._read = (self.client.read_input_registers if block.table == "input_registers"
                      else self.client.read_holding_registers)
        self.where = f"{host}:{port}"

    def read(self) -> dict[str, float]:
        """Values by name; ConnectionError naming the address when the service does not answer."""
        if not self.client.connected and not self.client.connect():
            raise ConnectionError(f"no answer from the service at {self.where}")
        try:
            r = self._read(self.codec.start, count=self.codec.words)
        except ModbusException as e:
            self.client.close()
            raise ConnectionError(f"{self.where}: {e}") from e
        if r.isError():
            raise ConnectionError(f"{self.where} refused the read: {r}")
        return dict(zip(self.codec.names, self.codec.decode(r.registers)))

    def close(self) -> None:
        self.client.close()
