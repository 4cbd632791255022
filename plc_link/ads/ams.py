"""AMS/TCP framing and the ADS command payloads (Beckhoff ADS specification; AdsLib's AmsHeader.h).

A frame on the wire is a 6-byte AMS/TCP header (2 bytes, 0 for an AMS frame, and the length of what
follows) and a 32-byte AMS header, then the command's payload. Everything is little-endian. (A nonzero
first field is a command to the AMS router itself, without an AMS header: `router`.)

AMS header: target Net ID (6), target port (2), source Net ID (6), source port (2), command (2),
state flags (2), payload length (4), error code (4), invoke ID (4).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

TCP_HEADER = struct.Struct("<HI")
AMS_HEADER = struct.Struct("<6sH6sHHHIII")
TCP_HEADER_SIZE = TCP_HEADER.size          # 6
AMS_HEADER_SIZE = AMS_HEADER.size          # 32

# commands
READ_DEVICE_INFO, READ, WRITE, READ_STATE, WRITE_CONTROL = 1, 2, 3, 4, 5
ADD_NOTIFICATION, DEL_NOTIFICATION, DEVICE_NOTIFICATION, READ_WRITE = 6, 7, 8, 9
COMMANDS = {READ_DEVICE_INFO, READ, WRITE, READ_STATE, WRITE_CONTROL, ADD_NOTIFICATION, DEL_NOTIFICATION,
            READ_WRITE}
COMMAND_NAMES = {READ_DEVICE_INFO: "ReadDeviceInfo", READ: "Read", WRITE: "Write", READ_STATE: "ReadState",
                 WRITE_CONTROL: "WriteControl", ADD_NOTIFICATION: "AddDeviceNotification",
                 DEL_NOTIFICATION: "DeleteDeviceNotification", READ_WRITE: "ReadWrite"}

# state flags: bit 0 response, bit 2 an ADS command (over TCP)
FLAG_RESPONSE = 0x0001
FLAG_ADS_COMMAND = 0x0004

SYSTEM_SERVICE_PORT = 10000     # TwinCAT's system service, on every AMS Net ID

# AMS-level (router) error codes, carried in the AMS header
ERR_TARGET_PORT_NOT_FOUND = 0x06
ERR_TARGET_MACHINE_NOT_FOUND = 0x07
ERR_INVALID_AMS_LENGTH = 0x0E

# ADS device error codes, carried in a response's result field
ADSERR_DEVICE_ERROR = 0x700
ADSERR_SRV_NOT_SUPP = 0x701
ADSERR_INVALID_GROUP = 0x702
ADSERR_INVALID_OFFSET = 0x703
ADSERR_INVALID_ACCESS = 0x704
ADSERR_INVALID_SIZE = 0x705
ADSERR_INVALID_DATA = 0x706
ADSERR_SYMBOL_NOT_FOUND = 0x710
ADSERR_TRANSMODE_NOT_SUPP = 0x713
ADSERR_NOTIFY_HANDLE_INVALID = 0x714
ADSERR_NO_MORE_HANDLES = 0x716

# ADS states (ReadState)
ADSSTATE_INIT, ADSSTATE_RUN, ADSSTATE_STOP = 3, 5, 6

# notification transmission modes
TRANS_SERVER_CYCLE, TRANS_SERVER_ON_CHANGE = 3, 4
TRANS_SERVER_CYCLE2, TRANS_SERVER_ON_CHANGE2 = 5, 6

FILETIME_EPOCH_OFFSET = 116_444_736_000_000_000   # 100 ns ticks from 1601-01-01 to 1970-01-01


class FrameError(Exception):
    """A frame the server cannot answer (no usable header): the connection is closed."""


def net_id_bytes(text: str) -> bytes:
    """``"127.0.0.1.1.1"`` -> its six bytes."""
    parts = text.split(".")
    if len(parts) != 6 or not all(p.isdigit() and int(p) <= 255 for p in parts):
        raise ValueError(f"{text!r} is not an AMS Net ID (six numbers 0..255 joined by dots)")
    return bytes(int(p) for p in parts)


def net_id_text(raw: bytes) -> str:
    return ".".join(str(b) for b in raw)


def filetime(stamp_ns: int) -> int:
    """Windows FILETIME (100 ns since 1601-01-01 UTC) of a ``time.time_ns()`` stamp."""
    return stamp_ns // 100 + FILETIME_EPOCH_OFFSET


@dataclass(frozen=True)
class AmsHeader:
    target: bytes
    target_port: int
    source: bytes
    source_port: int
    command: int
    flags: int
    length: int
    error: int
    invoke_id: int

    @classmethod
    def parse(cls, frame: bytes) -> AmsHeader:
        """The header of an AMS frame (the bytes after the AMS/TCP header)."""
        if len(frame) < AMS_HEADER_SIZE:
            raise FrameError(f"AMS frame of {len(frame)} bytes is shorter than its 32-byte header")
        return cls(*AMS_HEADER.unpack_from(frame))

    def reply(self, payload: bytes, error: int = 0) -> bytes:
        """The response frame to this request: addresses swapped, same command and invoke ID."""
        head = AMS_HEADER.pack(self.source, self.source_port, self.target, self.target_port, self.command,
                               FLAG_RESPONSE | FLAG_ADS_COMMAND, len(payload), error, self.invoke_id)
        return TCP_HEADER.pack(0, AMS_HEADER_SIZE + len(payload)) + head + payload


def request_frame(target: bytes, target_port: int, source: bytes, source_port: int, command: int,
                  payload: bytes, invoke_id: int = 0) -> bytes:
    """A request frame (the server sends DeviceNotification this way; tests send the others)."""
    head = AMS_HEADER.pack(target, target_port, source, source_port, command, FLAG_ADS_COMMAND, len(payload),
                           0, invoke_id)
    return TCP_HEADER.pack(0, AMS_HEADER_SIZE + len(payload)) + head + payload


# -- payloads ---------------------------------------------------------------------------------------
RESULT = struct.Struct("<I")
READ_REQ = struct.Struct("<III")            # group, offset, length
WRITE_REQ = struct.Struct("<III")           # group, offset, length, then data
READ_WRITE_REQ = struct.Struct("<IIII")     # group, offset, read length, write length, then data
READ_RES = struct.Struct("<II")             # result, length, then data
ADD_NOTE_REQ = struct.Struct("<IIIIII16x")  # group, offset, length, mode, max delay, cycle time (100 ns)
ADD_NOTE_RES = struct.Struct("<II")         # result, handle
DEVICE_INFO_RES = struct.Struct("<IBBH16s")
STATE_RES = struct.Struct("<IHH")
NOTE_HEAD = struct.Struct("<II")            # length, number of stamps
STAMP_HEAD = struct.Struct("<QI")           # FILETIME, number of samples
SAMPLE_HEAD = struct.Struct("<II")          # notification handle, size


def read_response(result: int, data: bytes = b"") -> bytes:
    """Read and ReadWrite answer with result and length even on error (AdsLib reads both)."""
    return READ_RES.pack(result, len(data)) + data


def result_response(result: int) -> bytes:
    return RESULT.pack(result)


def notification_payload(stamp_ns: int, samples: list[tuple[int, bytes]]) -> bytes:
    """A DeviceNotification payload: one stamp carrying ``samples`` as (handle, data)."""
    body = STAMP_HEAD.pack(filetime(stamp_ns), len(samples)) + b"".join(
        SAMPLE_HEAD.pack(h, len(d)) + d for h, d in samples)
    return NOTE_HEAD.pack(len(body) + 4, 1) + body
