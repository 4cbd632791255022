"""An ADS server (Beckhoff's AMS/TCP protocol) over the process image, for TwinCAT PLCs, HMIs and pyads.

`AdsServer(port, settings)` runs on an asyncio loop; see docs/ads.md for the symbols, the %MB mapping,
routes and errors. The names below are imported when first used, so that reading the ``ads:`` section
(`plc_link.ads.settings`, the health probe does) does not load the server.
"""

from __future__ import annotations

import importlib

_WHERE = {"AdsServer": "server", "AdsSettings": "settings", "ImagePort": "port", "Route": "settings",
          "Symbol": "symbols", "symbols_from_map": "symbols"}
__all__ = ["AdsServer", "AdsSettings", "ImagePort", "Route", "Symbol", "symbols_from_map"]


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)
