"""Device notifications of one connection: what each client asked for, and which samples are due.

A notification samples its bytes once per published cycle (`due`), never more often: cyclic ones when
their cycle time has passed since the last sample sent, on-change ones when the bytes differ from the
last sent. The first sample goes out at the first cycle after the notification is added, as TwinCAT
sends the current value at once. Samples of one cycle to one client port travel in one
DeviceNotification frame, stamped with that cycle's start time.
"""

from __future__ import annotations

from dataclasses import dataclass

from . import ams
from .area import GROUPS, AreaView
from .session import SYM_VAL_BY_HND, Session

MODES = {ams.TRANS_SERVER_CYCLE: False, ams.TRANS_SERVER_CYCLE2: False,
         ams.TRANS_SERVER_ON_CHANGE: True, ams.TRANS_SERVER_ON_CHANGE2: True}


@dataclass
class Notification:
    handle: int
    target: bytes           # the client's AMS Net ID and port, where the samples go
    target_port: int
    group: int
    offset: int
    length: int
    on_change: bool
    cycle_ns: int           # ns; 0 = every cycle
    last_ns: int | None = None
    last: bytes | None = None

    def sample(self, view: AreaView) -> bytes | None:
        """The bytes to send for this cycle, or None if none are due."""
        stamp = view.stamp_ns
        if self.last_ns is not None and stamp < self.last_ns:
            self.last_ns = stamp            # the wall clock stepped back: start counting afresh
        waited = self.last_ns is None or stamp - self.last_ns >= self.cycle_ns
        if not waited:
            return None
        err, data = view.read(self.group, self.offset, self.length)
        if err:
            return None
        if self.on_change:
            self.last_ns = stamp            # the sampling interval runs whether or not it changed
            if data == self.last:
                return None
        else:
            self.last_ns = stamp
        self.last = data
        return data


class Notifications:
    """The notifications of one connection.

    Parameters
    ----------
    session : the connection's session (its symbol handles resolve notifications by handle)
    limit : most notifications at once (ADS error 0x716 beyond)
    handle_ids : iterator of notification handles, shared by the server so handles are unique
    """

    def __init__(self, session: Session, limit: int, handle_ids):
        self.session, self.limit, self.handle_ids = session, limit, handle_ids
        self.items: dict[int, Notification] = {}

    def add(self, header: ams.AmsHeader, payload: bytes, view: AreaView) -> bytes:
        """Answer an AddDeviceNotification request."""
        if len(payload) != ams.ADD_NOTE_REQ.size:
            return ams.ADD_NOTE_RES.pack(ams.ADSERR_INVALID_SIZE, 0)
        group, offset, length, mode, _max_delay, cycle = ams.ADD_NOTE_REQ.unpack(payload)
        if mode not in MODES:
            return ams.ADD_NOTE_RES.pack(ams.ADSERR_TRANSMODE_NOT_SUPP, 0)
        if group == SYM_VAL_BY_HND:
            sym = self.session.handles.get(offset)
            if sym is None:
                return ams.ADD_NOTE_RES.pack(ams.ADSERR_SYMBOL_NOT_FOUND, 0)
            if length > sym.size:
                return ams.ADD_NOTE_RES.pack(ams.ADSERR_INVALID_SIZE, 0)
            group, offset = sym.group, sym.offset
        elif group not in GROUPS:
            return ams.ADD_NOTE_RES.pack(ams.ADSERR_INVALID_GROUP, 0)
        err = view.read(group, offset, length)[0] if length else ams.ADSERR_INVALID_SIZE
        if err:
            return ams.ADD_NOTE_RES.pack(err, 0)
        if len(self.items) >= self.limit:
            return ams.ADD_NOTE_RES.pack(ams.ADSERR_NO_MORE_HANDLES, 0)
        handle = next(self.handle_ids)
        self.items[handle] = Notification(handle, header.source, header.source_port, group, offset, length,
                                          MODES[mode], cycle * 100)
        return ams.ADD_NOTE_RES.pack(0, handle)

    def delete(self, payload: bytes) -> bytes:
        """Answer a DeleteDeviceNotification request."""
        if len(payload) != 4:
            return ams.result_response(ams.ADSERR_INVALID_SIZE)
        handle = int.from_bytes(payload, "little")
        return ams.result_response(0 if self.items.pop(handle, None) else ams.ADSERR_NOTIFY_HANDLE_INVALID)

    def due(self, view: AreaView, net_id: bytes, ams_port: int) -> list[bytes]:
        """DeviceNotification frames of this cycle, one per client port with samples due."""
        by_target: dict[tuple[bytes, int], list[tuple[int, bytes]]] = {}
        for n in self.items.values():
            data = n.sample(view)
            if data is not None:
                by_target.setdefault((n.target, n.target_port), []).append((n.handle, data))
        return [ams.request_frame(target, port, net_id, ams_port, ams.DEVICE_NOTIFICATION,
                                  ams.notification_payload(view.stamp_ns, samples))
                for (target, port), samples in by_target.items()]
