"""Routes: a request from an AMS Net ID or address not in the route table closes the connection, as
TwinCAT's router does; a known route is answered. Raw frames, the server in a spawn child."""

from __future__ import annotations

import socket

import pytest

from plc_link.ads import AdsSettings, ams
from testlib.ads_child import AdsChild

pytestmark = pytest.mark.realtime

NET_ID = "5.6.7.10.1.1"
KNOWN = "10.0.0.7.1.1"


def device_info(host: str, port: int, source: str) -> bytes:
    """The server's whole answer to one ReadDeviceInfo from ``source``, read until it closes or replies."""
    frame = ams.request_frame(ams.net_id_bytes(NET_ID), 851, ams.net_id_bytes(source), 30000,
                              ams.READ_DEVICE_INFO, b"", 77)
    with socket.create_connection((host, port), timeout=10.0) as s:
        s.sendall(frame)
        out = b""
        while len(out) < 6 + 32 + ams.DEVICE_INFO_RES.size:
            chunk = s.recv(4096)
            if not chunk:
                break
            out += chunk
    return out


def test_unknown_net_id_is_disconnected_and_a_known_route_is_answered(tmp_path):
    routes = [{"net_id": KNOWN, "address": "127.0.0.1"}]
    log = tmp_path / "ads.log"
    with AdsChild(net_id=NET_ID, allow_loopback=False, routes=routes, log_path=str(log)) as child:
        assert device_info(child.host, child.port, "10.0.0.8.1.1") == b""           # closed, no reply
        reply = device_info(child.host, child.port, KNOWN)
        h = ams.AmsHeader.parse(reply[6:])
        assert (h.invoke_id, h.error, h.flags & ams.FLAG_RESPONSE) == (77, 0, 1)
        result, *_ , name = ams.DEVICE_INFO_RES.unpack_from(reply, 38)
        assert result == 0 and name.rstrip(b"\0") == b"stiffcomp"
    assert "no route for this AMS Net ID (closed): 1 time(s), first report (Net ID 10.0.0.8.1.1)" in log.read_text()


def test_default_accepts_loopback_only():
    s = AdsSettings()
    assert s.allows("127.0.0.1", "1.2.3.4.1.1") and s.allows("127.3.4.5") and s.allows("::1")
    assert not s.allows("192.168.1.10") and not s.allows("192.168.1.10", "1.2.3.4.1.1")
    r = AdsSettings(allow_loopback=False, routes=[{"net_id": KNOWN, "address": "192.168.1.10"}])
    assert r.allows("192.168.1.10", KNOWN) and not r.allows("192.168.1.10", "1.2.3.4.1.1")
    assert not r.allows("127.0.0.1", KNOWN)


def test_settings_refuse_bad_net_ids_unknown_keys_and_nan():
    import pytest
    from pydantic import ValidationError

    for bad in ({"net_id": "1.2.3.4.1"}, {"net_id": "1.2.3.4.1.256"}, {"notify_poll": 0.001},
                {"notify_poll_s": float("nan")}, {"routes": [{"net_id": KNOWN, "address": "not-an-ip"}]}):
        with pytest.raises(ValidationError):
            AdsSettings(**bad)
