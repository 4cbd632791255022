"""The shared memory of the process image and of the trace ring goes with them, and no view of it outlives it.

A memoryview over the memory (the image's counters, the ring's count) that is still alive when the
SharedMemory is finalized makes its close fail ("BufferError: cannot close exported pointers exist",
printed by the collector in whatever test runs then) and keeps the name; an array left over it after close
points at memory no longer mapped.
"""

from __future__ import annotations

import gc
import sys
import weakref
from multiprocessing.shared_memory import SharedMemory

import pytest

from hil.testing import CONFIG, free_port, write_config
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from service.app import Service
from service.config import load_config
from service.trace import TraceRing
from testlib.common import wait_for

pytestmark = pytest.mark.realtime

MAP = RegisterMap.from_yaml(CONFIG / "registers.yaml")


@pytest.fixture
def unraisable(monkeypatch) -> list:
    """The exceptions raised where nobody can catch them (a finalizer's), while the test runs."""
    seen: list = []
    monkeypatch.setattr(sys, "unraisablehook", seen.append)
    return seen


@pytest.mark.parametrize("in_cycle", [False, True], ids=["dropped", "collected in a reference cycle"])
@pytest.mark.parametrize("make", [lambda: ProcessImage(MAP), lambda: TraceRing(rows=64)],
                         ids=["process image", "trace ring"])
def test_one_never_closed_lets_its_memory_go_when_it_goes(make, in_cycle, unraisable):
    """A test that never stops its service, a start that fails half-way: the object goes without `close`."""
    obj = make()
    name = obj.shm.name
    if in_cycle:
        obj.me = obj            # as a Service holds its image: only the cyclic collector frees it
    gone = weakref.ref(obj)
    del obj
    gc.collect()
    assert gone() is None
    assert [f"{u.exc_type.__name__}: {u.exc_value}" for u in unraisable] == []
    with pytest.raises(FileNotFoundError):
        SharedMemory(name=name)          # its creator freed the name too


def test_close_then_collection_is_quiet(unraisable):
    image, ring = ProcessImage(MAP), TraceRing(rows=64)
    image.close()
    ring.close()
    image.close()               # twice is harmless
    del image, ring
    gc.collect()
    assert unraisable == []


def test_a_stopped_service_keeps_no_array_over_its_image(tmp_path):
    """The compiled steady cycle's call holds the image's bytes and timing ring: gone with the stop."""
    service = Service(load_config(write_config(tmp_path, {"plc": {"port": free_port()}})))
    try:
        service.start()
        assert wait_for(lambda: service._steady is not None and service._steady.call is not None, timeout=120), \
            "the compiled steady cycle never armed"
        arrays = [weakref.ref(service.image.bytes), weakref.ref(service.image._timing)]
    finally:
        service.stop()
    gc.collect()
    assert [r() is None for r in arrays] == [True, True], "an array over the unmapped image outlived the stop"
