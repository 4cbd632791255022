"""An ADS server (Beckhoff's AMS/TCP protocol) over the process image, for TwinCAT PLCs, HMIs and pyads.

`AdsServer(port, settings)` runs on an asyncio loop; see docs/ads.md for the symbols, the %MB mapping,
routes and errors.
"""

from .port import ImagePort
from .server import AdsServer
from .settings import AdsSettings, Route
from .symbols import Symbol, symbols_from_map

__all__ = ["AdsServer", "AdsSettings", "ImagePort", "Route", "Symbol", "symbols_from_map"]
