"""A pyads connection to the service's ADS server, for the image test and the benchmark.

pyads wraps Beckhoff's AdsLib, which always dials the AMS/TCP port 48898. `open_ads` says why not
in one line when pyads is missing or nothing listens there, so a caller can report it instead of
failing with AdsLib's error codes.
"""

from __future__ import annotations

import socket

ADS_TCP_PORT = 48898
CYCLE_SYMBOL = "TwinCAT_SystemInfoVarList._TaskInfo[1].CycleCount"


def open_ads(host: str = "127.0.0.1", net_id: str = "127.0.0.1.1.1", ams_port: int = 851):
    """(an open ``pyads.Connection``, "") or (None, the reason in one line)."""
    try:
        import pyads
    except ImportError:
        return None, "pyads is not installed (pip install -e '.[ads]')"
    with socket.socket() as s:
        s.settimeout(1.0)
        if s.connect_ex((host, ADS_TCP_PORT)) != 0:
            return None, f"no ADS server at {host}:{ADS_TCP_PORT} (the I/O process's ADS server, issue 10)"
    conn = pyads.Connection(net_id, ams_port, host)
    try:
        conn.open()
    except pyads.ADSError as e:
        return None, f"ADS {host}:{ADS_TCP_PORT}: {e}"
    return conn, ""


def read_cycle_count(conn) -> int:
    """The task's cycle counter, by symbol name, as a TwinCAT client reads it."""
    import pyads

    return int(conn.read_by_name(CYCLE_SYMBOL, pyads.PLCTYPE_UDINT))
