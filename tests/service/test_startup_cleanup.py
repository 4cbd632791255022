"""Start-up failures free what was opened: shared memory, buses, signal handlers; errors exit 2."""

from __future__ import annotations

import os
import signal
import socket

import numpy as np
import pytest

from hil.demo_log import write_log
from hil.testing import free_port, write_config
from service.app import Service
from service.config import load_config
from service.errors import SourceError
from tools.cli import main


def shm_segments() -> set[str]:
    return set(os.listdir("/dev/shm")) if os.path.isdir("/dev/shm") else set()


pytestmark = [pytest.mark.skipif(not os.path.isdir("/dev/shm"), reason="needs POSIX shared memory in /dev/shm"),
              pytest.mark.serial]       # /dev/shm is the host's: another worker's segments come and go in it


def test_a_source_that_fails_to_open_frees_the_shared_image(tmp_path):
    log = tmp_path / "other_sensor.blf"
    write_log(log, np.zeros((5, 6)))                      # a log of the sensor at base id 0x020
    cfg = load_config(write_config(tmp_path, {
        "plc": {"port": free_port()},
        "source": {"type": "replay", "replay": {"file": str(log)}, "ati": {"base_id": 0x030}}}))
    before = shm_segments()
    with pytest.raises(SourceError, match="no sample frame"):
        Service(cfg)
    assert shm_segments() - before == set()


def test_run_on_a_port_in_use_exits_2_and_leaves_nothing(tmp_path, capsys):
    with socket.socket() as busy:
        busy.bind(("127.0.0.1", 0))
        busy.listen()
        cfg = write_config(tmp_path, {"plc": {"port": busy.getsockname()[1]}})
        before = shm_segments()
        handlers = {s: signal.getsignal(s) for s in (signal.SIGINT, signal.SIGTERM)}
        assert main(["run", "--config", str(cfg), "--duration", "1"]) == 2
    assert shm_segments() - before == set()
    assert {s: signal.getsignal(s) for s in handlers} == handlers
    assert "error" in capsys.readouterr().err


def test_record_to_a_bad_path_exits_2_without_a_traceback(tmp_path, capsys):
    out = tmp_path / "no" / "such" / "dir" / "log.blf"
    rc = main(["record", str(out), "--interface", "virtual", "--channel", "rec_bad", "--virtual-sensor",
               "--duration", "0.2"])
    err = capsys.readouterr().err
    assert rc == 2 and "cannot write the log" in err and "Traceback" not in err
