"""Fixtures of the PLC link's tests: every test leaves no thread, socket or process behind."""

import pyads
import pytest

from testlib.ads_child import AdsChild


@pytest.fixture(autouse=True)
def _leak_check(no_leaks):
    """The root conftest's leak check, around every test here."""
    yield


@pytest.fixture
def server(request):
    """The ADS server in a child process, at the requesting module's ``NET_ID``."""
    with AdsChild(net_id=request.module.NET_ID) as child:
        yield child


@pytest.fixture
def plc(server, request):
    """A pyads connection to `server`'s PLC port (851)."""
    conn = pyads.Connection(request.module.NET_ID, 851, f"{server.host}:{server.port}")
    conn.open()
    yield conn
    conn.close()
