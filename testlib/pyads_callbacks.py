"""Deleting a pyads notification without a crash.

pyads drops its reference to a notification's C callback as soon as ``del_device_notification``
has asked AdsLib to delete it. AdsLib's dispatcher thread may be running that callback at that
moment: it looks the notification up under its lock and calls it outside. When the C thunk is
freed under it, the process ends with SIGSEGV (seen once in a full run: the dispatcher in pyads'
``wrapper``, the test's thread in ``del_device_notification``). Holding every callback of the
process until it exits closes that window. docs/ads.md tells users the same.
"""

from __future__ import annotations

import pyads
from pyads import pyads_ex

_HELD: list = []          # the C callbacks of deleted notifications, alive until the process ends


def delete_notification(plc: pyads.Connection, handles: tuple[int, int]) -> None:
    _HELD.extend(pyads_ex.callback_store.values())
    plc.del_device_notification(*handles)
