"""8 pyads clients, each in a process of its own, read by handle as fast as they can: every read
answers, and each client sees the cycle count never go back. No timing is asserted."""

from __future__ import annotations

import multiprocessing

import pytest

from testlib.ads_child import AdsChild, read_by_handle

pytestmark = pytest.mark.realtime

NET_ID = "5.6.7.12.1.1"


def test_eight_pyads_clients_reading_by_handle():
    with AdsChild(net_id=NET_ID) as child:
        ctx = multiprocessing.get_context("spawn")
        with ctx.Pool(8) as pool:
            runs = pool.starmap(read_by_handle, [(child.host, child.port, NET_ID, "GVL_Comp.cycle_count", 300)] * 8)
            pool.close()
            pool.join()
    assert [len(r) for r in runs] == [300] * 8
    for values in runs:
        assert values == sorted(values) and values[-1] > 0
    assert child.report["tampered"] == 0
