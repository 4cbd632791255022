"""The cell network's ADS client: a PLC's ADSREAD and ADSWRITE sent to the service's ADS server over AMS/TCP, as a
TwinCAT runtime's router sends them (Beckhoff, "ADS specification": the AMS/TCP header, the 32-byte AMS header,
the ADS Read and Write commands; the frames are `plc_link.ads.ams`'s, the service's own reading of them).

One request at a time, answered before the next is sent: the virtual PLC sends a request when its block starts it
and takes the answer at the block's next call (`hil.cell_network`).
"""

from __future__ import annotations

import socket

from plc_link.ads import ams

SOURCE_PORT = 32905                 # a PLC runtime's ADS client port range starts at 32768 (TwinCAT)
FAILED = ams.ADSERR_DEVICE_ERROR    # no answer, or one that does not belong to the request


class AdsClient:
    """Parameters
    ----------
    host, port : the service's ADS server (AMS/TCP)
    source_net_id : the PLC's own AMS Net ID (the service's route for it: ``ads.allow_loopback`` on one host)
    timeout_s : how long one answer is awaited
    """

    def __init__(self, host: str, port: int, source_net_id: str = "127.0.0.1.1.2", timeout_s: float = 0.1):
        self.address = (host, port)
        self.source = ams.net_id_bytes(source_net_id)
        self.timeout_s = timeout_s
        self.sock: socket.socket | None = None
        self.invoke = 0

    def connect(self) -> bool:
        try:
            self.sock = socket.create_connection(self.address, timeout=self.timeout_s)
            self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        except OSError:
            self.sock = None
        return self.sock is not None

    def close(self) -> None:
        if self.sock is not None:
            self.sock.close()
            self.sock = None

    def read(self, net_id: str, port: int, group: int, offset: int, length: int) -> tuple[int, bytes]:
        """(ADS result, data) of an ADS Read."""
        error, payload = self._exchange(net_id, port, ams.READ, ams.READ_REQ.pack(group, offset, length))
        if error or len(payload) < ams.READ_RES.size:
            return error or FAILED, b""
        result, n = ams.READ_RES.unpack_from(payload)
        return result, payload[ams.READ_RES.size:ams.READ_RES.size + n]

    def write(self, net_id: str, port: int, group: int, offset: int, data: bytes) -> int:
        """The ADS result of an ADS Write."""
        error, payload = self._exchange(net_id, port, ams.WRITE, ams.WRITE_REQ.pack(group, offset, len(data)) + data)
        if error or len(payload) < ams.RESULT.size:
            return error or FAILED
        return ams.RESULT.unpack_from(payload)[0]

    def _exchange(self, net_id: str, port: int, command: int, body: bytes) -> tuple[int, bytes]:
        """(the AMS header's error, the answer's ADS payload); the payload is empty when the answer was not this
        request's. OSError on a lost link or a late answer (the socket's timeout)."""
        if self.sock is None:
            raise ConnectionError("not connected")
        self.invoke = (self.invoke + 1) & 0xFFFFFFFF
        self.sock.sendall(ams.request_frame(ams.net_id_bytes(net_id), port, self.source, SOURCE_PORT, command, body,
                                            self.invoke))
        head = self._recv(ams.TCP_HEADER_SIZE)
        _, length = ams.TCP_HEADER.unpack(head)
        frame = self._recv(length)
        header = ams.AmsHeader.parse(frame)
        if header.invoke_id != self.invoke or header.command != command:
            return 0, b""
        return header.error, frame[ams.AMS_HEADER_SIZE:]

    def _recv(self, n: int) -> bytes:
        out = b""
        while len(out) < n:
            chunk = self.sock.recv(n - len(out))
            if not chunk:
                raise ConnectionError("the ADS server closed the connection")
            out += chunk
        return out
