"""One client connection's view of the device: its symbol handles and the Read/Write/ReadWrite services.

Every request is answered from one snapshot of the image, so a sum read returns values of one cycle.
Bad requests get their ADS error and change nothing: writes go only through `Layout.write`, which
admits whole from_plc registers and nothing else.
"""

from __future__ import annotations

import itertools
import struct

from plc_link.register_map import RegisterMap

from . import ams
from .area import GROUPS, MB_GROUP, AreaView, Layout
from .port import ImagePort
from .symbols import Symbol, SymbolTable

SYM_HND_BY_NAME, SYM_VAL_BY_NAME, SYM_VAL_BY_HND, SYM_RELEASE_HND = 0xF003, 0xF004, 0xF005, 0xF006
SYM_INFO_BY_NAME_EX, SYM_UPLOAD, SYM_UPLOAD_INFO, SYM_UPLOAD_INFO2 = 0xF009, 0xF00B, 0xF00C, 0xF00F
SYM_DT_UPLOAD, SYM_DT_INFO_BY_NAME = 0xF00E, 0xF011
SUM_READ, SUM_WRITE, SUM_READ_WRITE = 0xF080, 0xF081, 0xF082
SUM_GROUPS = {SUM_READ, SUM_WRITE, SUM_READ_WRITE}
SUB3 = struct.Struct("<III")        # sum read/write sub-request: group, offset, length
SUB4 = struct.Struct("<IIII")       # sum read-write sub-request: group, offset, read length, write length
HANDLE = struct.Struct("<I")
HANDLE_INFO = struct.Struct("<IIIH")  # handle, size, ADS data type, type name length; then the name, NUL


class Device:
    """What every connection shares: the image port, the layout, the symbols and the limits.

    The symbol version (0xF008, one byte) belongs to the running device: it starts at
    ``FIRST_SYMBOL_VERSION`` and `install` moves it on by one (modulo 256) whenever the symbols it
    installs differ from those served, so a client that cached the upload notices any change. The same
    set installed again keeps it.

    Parameters
    ----------
    port : ImagePort
    max_handles, max_sum_requests, max_frame_bytes : limits (`AdsSettings`)
    """

    FIRST_SYMBOL_VERSION = 1

    def __init__(self, port: ImagePort, max_handles: int = 1024, max_sum_requests: int = 500,
                 max_frame_bytes: int = 1 << 20):
        self.port = port
        self.max_handles, self.max_sum, self.max_frame = max_handles, max_sum_requests, max_frame_bytes
        self.handle_ids = itertools.count(1)
        self.symbols: SymbolTable | None = None
        self.symbol_version = self.FIRST_SYMBOL_VERSION
        self.install(port.rmap)

    def install(self, rmap: RegisterMap) -> int:
        """Serve the layout and symbols of ``rmap`` from now on; returns the symbol version.

        The one place a symbol table is installed: at start, and whenever the register map is replaced
        while the service runs. The version changes exactly when the symbol upload (names, types,
        addresses, sizes, comments) differs from the one served before.
        """
        table = SymbolTable(rmap)
        version = self.symbol_version
        if self.symbols is not None and table.upload != self.symbols.upload:
            version = (version + 1) % 256
        self.layout, self.symbols, self.symbol_version = Layout(rmap), table, version
        return version

    def view(self) -> AreaView:
        """The areas of the newest published cycle."""
        return self.view_of(self.port.snapshot())

    def view_of(self, snap: tuple[int, int, list[int], list[int]]) -> AreaView:
        """The areas of ``snap`` (an `ImagePort.snapshot`)."""
        return AreaView(self.layout, snap, self.symbol_version)


class Session:
    """The requests of one connection; symbol handles live as long as it."""

    def __init__(self, device: Device):
        self.device = device
        self.handles: dict[int, Symbol] = {}

    # -- Read --------------------------------------------------------------------------------------
    def read(self, view: AreaView, group: int, offset: int, length: int) -> tuple[int, bytes]:
        if group in GROUPS:
            return view.read(group, offset, length)
        if group == SYM_VAL_BY_HND:
            sym = self.handles.get(offset)
            if sym is None:
                return ams.ADSERR_SYMBOL_NOT_FOUND, b""
            if length > sym.size:
                return ams.ADSERR_INVALID_SIZE, b""
            return view.read(sym.group, sym.offset, length)
        symbols = self.device.symbols
        blob = {SYM_UPLOAD: symbols.upload, SYM_UPLOAD_INFO: symbols.upload_info,
                SYM_UPLOAD_INFO2: symbols.upload_info2, SYM_DT_UPLOAD: symbols.types.upload}.get(group)
        if blob is None:
            return ams.ADSERR_INVALID_GROUP, b""
        return (0, blob) if length >= len(blob) else (ams.ADSERR_INVALID_SIZE, b"")

    # -- Write -------------------------------------------------------------------------------------
    def write(self, group: int, offset: int, data: bytes) -> int:
        layout: Layout = self.device.layout
        if group == MB_GROUP:
            return layout.write(self.device.port, offset, data)
        if group in GROUPS:
            return ams.ADSERR_INVALID_ACCESS        # the task info, the runtime state, the symbol version
        if group == SYM_VAL_BY_HND:
            sym = self.handles.get(offset)
            if sym is None:
                return ams.ADSERR_SYMBOL_NOT_FOUND
            if not sym.writable:
                return ams.ADSERR_INVALID_ACCESS
            if len(data) != sym.size:
                return ams.ADSERR_INVALID_SIZE
            return layout.write(self.device.port, sym.offset, data)
        if group == SYM_RELEASE_HND:
            if len(data) != HANDLE.size:
                return ams.ADSERR_INVALID_SIZE
            return 0 if self.handles.pop(HANDLE.unpack(data)[0], None) else ams.ADSERR_SYMBOL_NOT_FOUND
        return ams.ADSERR_INVALID_GROUP

    # -- ReadWrite ---------------------------------------------------------------------------------
    def read_write(self, view: AreaView, group: int, offset: int, rlen: int, data: bytes) -> tuple[int, bytes]:
        symbols = self.device.symbols
        if group == SYM_HND_BY_NAME:
            sym = symbols.find(data)
            if sym is None:
                return ams.ADSERR_SYMBOL_NOT_FOUND, b""
            if rlen < HANDLE.size:
                return ams.ADSERR_INVALID_SIZE, b""
            if len(self.handles) >= self.device.max_handles:
                return ams.ADSERR_NO_MORE_HANDLES, b""
            handle = next(self.device.handle_ids)
            self.handles[handle] = sym
            return 0, self._handle_answer(handle, sym, rlen)
        if group == SYM_VAL_BY_NAME:            # value by name in one request, without a handle
            sym = symbols.find(data)
            if sym is None:
                return ams.ADSERR_SYMBOL_NOT_FOUND, b""
            return view.read(sym.group, sym.offset, sym.size) if rlen >= sym.size else (ams.ADSERR_INVALID_SIZE, b"")
        if group in (SYM_INFO_BY_NAME_EX, SYM_DT_INFO_BY_NAME):
            found = symbols.find(data) if group == SYM_INFO_BY_NAME_EX else symbols.types.find(data)
            if found is None:
                return ams.ADSERR_SYMBOL_NOT_FOUND, b""
            entry = found.entry()
            return (0, entry) if rlen >= len(entry) else (ams.ADSERR_INVALID_SIZE, b"")
        if group == SUM_READ:
            return self._sum_read(view, offset, rlen, data)
        if group == SUM_WRITE:
            return self._sum_write(offset, rlen, data)
        if group == SUM_READ_WRITE:
            return self._sum_read_write(view, offset, rlen, data)
        return ams.ADSERR_INVALID_GROUP, b""

    @staticmethod
    def _handle_answer(handle: int, sym: Symbol, rlen: int) -> bytes:
        """A runtime's answer to handle by name: with room for it, the handle, the size, the ADS data type
        and the type's name (ads-client reads this); else the handle alone (AdsLib and pyads read 4 bytes)."""
        name = sym.type_name.encode("latin-1")
        full = HANDLE_INFO.pack(handle, sym.size, sym.ads_type, len(name)) + name + b"\0"
        return full if rlen >= len(full) else HANDLE.pack(handle)

    # -- sum commands: n sub-requests in one frame, a result each ----------------------------------
    def _sum_count(self, n: int, head: int, data: bytes) -> bool:
        return 0 < n <= self.device.max_sum and len(data) >= n * head

    def _sum_read(self, view: AreaView, n: int, rlen: int, data: bytes) -> tuple[int, bytes]:
        if not self._sum_count(n, SUB3.size, data) or len(data) != n * SUB3.size:
            return ams.ADSERR_INVALID_SIZE, b""
        subs = [SUB3.unpack_from(data, k * SUB3.size) for k in range(n)]
        total = 4 * n + sum(length for _, _, length in subs)
        if total > rlen or total > self.device.max_frame:
            return ams.ADSERR_INVALID_SIZE, b""
        results, chunks = [], []
        for group, offset, length in subs:
            err, chunk = (ams.ADSERR_INVALID_GROUP, b"") if group in SUM_GROUPS else \
                self.read(view, group, offset, length)
            results.append(err)
            # the data part keeps every sub-request's place, zero-filled where it failed
            chunks.append(chunk if not err else bytes(length))
        return 0, struct.pack(f"<{n}I", *results) + b"".join(chunks)

    def _sum_write(self, n: int, rlen: int, data: bytes) -> tuple[int, bytes]:
        if not self._sum_count(n, SUB3.size, data) or rlen < 4 * n:
            return ams.ADSERR_INVALID_SIZE, b""
        subs = [SUB3.unpack_from(data, k * SUB3.size) for k in range(n)]
        pos = n * SUB3.size
        if pos + sum(length for _, _, length in subs) != len(data):
            return ams.ADSERR_INVALID_SIZE, b""
        results = []
        for group, offset, length in subs:
            chunk = data[pos: pos + length]
            pos += length
            results.append(ams.ADSERR_INVALID_GROUP if group in SUM_GROUPS else self.write(group, offset, chunk))
        return 0, struct.pack(f"<{n}I", *results)

    def _sum_read_write(self, view: AreaView, n: int, rlen: int, data: bytes) -> tuple[int, bytes]:
        if not self._sum_count(n, SUB4.size, data):
            return ams.ADSERR_INVALID_SIZE, b""
        subs = [SUB4.unpack_from(data, k * SUB4.size) for k in range(n)]
        pos = n * SUB4.size
        if pos + sum(wl for *_, wl in subs) != len(data):
            return ams.ADSERR_INVALID_SIZE, b""
        heads, chunks = [], []
        for group, offset, rl, wl in subs:
            chunk = data[pos: pos + wl]
            pos += wl
            err, out = (ams.ADSERR_INVALID_GROUP, b"") if group in SUM_GROUPS else \
                self.read_write(view, group, offset, rl, chunk)
            heads.append((err, len(out)))
            chunks.append(out)
        body = b"".join(struct.pack("<II", *h) for h in heads) + b"".join(chunks)
        return (0, body) if len(body) <= rlen else (ams.ADSERR_INVALID_SIZE, b"")
