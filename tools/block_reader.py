"""The to_plc block of a running service, decoded by register name: `stiffcomp status` reads it for its
view, `stiffcomp health` where the service serves no HTTP. Over Modbus TCP, Modbus/TCP Security (a
client certificate in an `ssl.SSLContext`) or ADS (pyads); each reader has ``read()``, ``close()`` and
says where it reads (``what``, ``where``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

from pymodbus.client import ModbusTcpClient, ModbusTlsClient
from pymodbus.exceptions import ModbusException

if TYPE_CHECKING:
    import ssl

    from plc_link.register_map import RegisterMap


class BlockReader:
    """The to_plc block over Modbus, decoded into values by register name; with ``sslctx``, over
    Modbus/TCP Security (pymodbus' TLS client sends no server name: build ``sslctx`` without the name
    check, `io_base.tls.client_context`)."""

    def __init__(self, rmap: RegisterMap, host: str, port: int, timeout_s: float = 0.5,
                 sslctx: ssl.SSLContext | None = None):
        block = rmap.blocks["to_plc"]
        self.codec = rmap.codecs["to_plc"]
        if sslctx is None:
            self.client = ModbusTcpClient(host, port=port, timeout=timeout_s, retries=0)
        else:
            self.client = ModbusTlsClient(host, port=port, sslctx=sslctx, timeout=timeout_s, retries=0)
        self._read = (self.client.read_input_registers if block.table == "input_registers"
                      else self.client.read_holding_registers)
        self.what = "Modbus" if sslctx is None else "Modbus/TCP Security"
        self.where = f"{host}:{port}"

    def read(self) -> dict[str, float]:
        """Values by name; ConnectionError naming the address when the service does not answer."""
        if not self.client.connected and not self.client.connect():
            raise ConnectionError(f"no answer from the service at {self.where}"
                                  + (" (Modbus/TCP Security)" if self.what != "Modbus" else ""))
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


class AdsReader:
    """The to_plc registers over ADS: their ``GVL_Comp`` symbols in one sum read, by name."""

    what = "ADS"

    def __init__(self, rmap: RegisterMap, host: str, port: int, net_id: str, ams_port: int,
                 timeout_ms: int = 500):
        try:
            import pyads  # noqa: F401
        except ImportError:
            raise ValueError("reading over ADS needs pyads (pip install -e '.[ads]')") from None
        from plc_link.ads.symbols import GVL

        self.names = rmap.codecs["to_plc"].names
        self.symbols = [f"{GVL}.{n}" for n in self.names]
        self.address = (host, net_id, ams_port, port)
        self.timeout_ms = timeout_ms
        self.where = f"{host}:{port}"
        self.conn = None

    def read(self) -> dict[str, float]:
        """Values by name; ConnectionError naming the address when the service does not answer."""
        import pyads

        from .pyads_connection import open_ads

        if self.conn is None:
            self.conn, why = open_ads(*self.address)
            if self.conn is None:
                raise ConnectionError(f"no answer from the service over ADS: {why}")
            self.conn.set_timeout(self.timeout_ms)
        try:
            values = self.conn.read_list_by_name(self.symbols)
        except pyads.ADSError as e:
            self.close()
            raise ConnectionError(f"{self.where}: {e}") from e
        bad = [s for s in self.symbols if not isinstance(values.get(s), (int, float))]
        if bad:                 # a sum read answers per symbol: an error code string in place of a value
            raise ConnectionError(f"{self.where} refused {bad[0]}: {values.get(bad[0])}")
        return {n: float(values[s]) for n, s in zip(self.names, self.symbols)}

    def close(self) -> None:
        if self.conn is not None:
            self.conn.close()
            self.conn = None
