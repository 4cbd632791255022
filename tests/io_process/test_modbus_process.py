"""The I/O process: a child that dies while starting is a prompt PlcError; the image's memory is freed
even while a view of it is alive."""

from __future__ import annotations

import time
from multiprocessing.shared_memory import SharedMemory

import numpy as np
import pytest

from hil.testing import CONFIG, free_port
from io_base.errors import PlcError
from io_process.process import IoProcess
from io_process.server import IoSettings
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from plc_link.settings import PlcSettings

pytestmark = pytest.mark.realtime


def test_a_child_that_dies_while_starting_is_a_prompt_plc_error():
    image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    server = IoProcess(image, IoSettings(plc=PlcSettings(port=free_port())))
    image.close()                      # the child cannot attach to the image: it dies unpickling it
    t0 = time.monotonic()
    with pytest.raises(PlcError, match="died"):
        server.start(timeout=30.0)
    assert time.monotonic() - t0 < 15.0
    assert not server.alive


def test_close_frees_the_memory_even_with_a_view_alive():
    image = ProcessImage(RegisterMap.from_yaml(CONFIG / "registers.yaml"))
    name = image.shm.name
    view = np.frombuffer(image.shm.buf, dtype=np.uint8)     # an export still alive: close() cannot unmap
    image.close()
    with pytest.raises(FileNotFoundError):
        SharedMemory(name=name)
    del view
    image.shm.close()
