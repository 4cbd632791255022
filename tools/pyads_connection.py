"""A pyads connection to the service's ADS server: for the health probe's ADS reader (`tools.block_reader`),
the image test and the benchmark.

pyads wraps Beckhoff's AdsLib, which always dials the AMS/TCP port 48898. `open_ads` says why not
in one line when pyads is missing or nothing listens there, so a caller can report it instead of
failing with AdsLib's error codes.
"""

from __future__ import annotations

import socket

ADS_TCP_PORT = 48898
CYCLE_SYMBOL = "TwinCAT_SystemInfoVarList._TaskInfo[1].CycleCount"


def open_ads(host: str = "127.0.0.1", net_id: str = "127.0.0.1.1.1", ams_port: int = 851,
             tcp_port: int = ADS_TCP_PORT):
    """(an open ``pyads.Connection``, "") or (None, the reason in one line); ``tcp_port`` other than 48898
    is dialled as ``host:port``, which AdsLib accepts."""
    try:
        import pyads
    except ImportError:
        return None, "pyads is not installed (pip install -e '.[ads]')"
    with socket.socket() as s:
        s.settimeout(1.0)
        if s.connect_ex((host, tcp_port)) != 0:
            return None, f"no ADS server at {host}:{tcp_port}"
    conn = pyads.Connection(net_id, ams_port, host if tcp_port == ADS_TCP_PORT else f"{host}:{tcp_port}")
    try:
        conn.open()
    except pyads.ADSError as e:
        return None, f"ADS {host}:{tcp_port}: {e}"
    return conn, ""


def read_cycle_count(conn) -> int:
    """The task's cycle counter, by symbol name, as a TwinCAT client reads it."""
    import pyads

    return int(conn.read_by_name(CYCLE_SYMBOL, pyads.PLCTYPE_UDINT))
