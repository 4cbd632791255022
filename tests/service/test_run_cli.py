"""`stiffcomp run` end to end: a real process, a duration, SIGTERM, the stats JSON, clean exit 0."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from hil.testing import ROOT, free_port, write_config
from plc_link.contract import Status, TaskState
from service.accelerometer import BoxReplay
from service.config import load_config
from stiffness.data.trace_file import read_trace

pytestmark = pytest.mark.realtime

STATS_KEYS = {"cycles", "exceed_count", "exec_us", "period_jitter_us"}


def stiffcomp(*args):
    return [sys.executable, "-m", "tools.cli", *args]


def test_run_for_a_duration_writes_stats_and_a_trace_of_every_cycle_and_exits_0(tmp_path):
    """The run's statistics, and its trace (--trace, issue 29): one row per cycle, none lost, in order, the
    PLC's joints in every row, the last row the stopped state."""
    cfg = write_config(tmp_path, {"plc": {"port": free_port()}})
    stats, trace = tmp_path / "stats.json", tmp_path / "trace.csv"
    p = subprocess.run(stiffcomp("run", "--config", str(cfg), "--duration", "1.5", "--stats-json", str(stats),
                                 "--trace", str(trace)),
                       cwd=ROOT, check=False, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    s = json.loads(stats.read_text())
    assert STATS_KEYS <= set(s)
    assert s["cycles"] > 0 and s["status"] == "stopped"
    assert "status: stopped" in p.stderr
    t = read_trace(trace)
    assert s["trace"] == {"file": str(trace), "cycles": s["cycles"], "written": s["cycles"], "lost": 0}
    np.testing.assert_array_equal(t.cycle, np.arange(1, s["cycles"] + 1))
    assert np.all(np.diff(t.time_s) > 0)
    np.testing.assert_allclose(t.q_deg, np.tile(load_config(cfg).plc.initial_q_deg, (len(t), 1)), atol=1e-4)
    assert t.column("task_state")[-1] == TaskState.STOP and np.all(t.column("task_state")[:-1] == TaskState.RUN)


def test_sigterm_and_ctrl_c_stop_cleanly_with_exit_0(tmp_path):
    for sig in (signal.SIGTERM, signal.SIGINT):
        cfg = write_config(tmp_path, {"plc": {"port": free_port()}})
        stats = tmp_path / f"stats_{int(sig)}.json"
        p = subprocess.Popen(stiffcomp("run", "--config", str(cfg), "--stats-json", str(stats)), cwd=ROOT,
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            deadline = time.monotonic() + 30
            while time.monotonic() < deadline:
                line = p.stderr.readline()
                if "service running" in line or not line:
                    break
            time.sleep(0.3)
            p.send_signal(sig)
            _, err = p.communicate(timeout=30)
        finally:
            if p.poll() is None:
                p.kill()
                p.communicate()
        assert p.returncode == 0, err
        assert json.loads(stats.read_text())["status"] == "stopped"


def help_trace_columns(text: str) -> list[str]:
    """The columns `stiffcomp run --help` lists for --trace, ``q1_deg..q6_deg`` spelled out."""
    text = " ".join(text.split())
    listed = re.search(r"with the columns: (.*?)\. ", text)
    assert listed, f"run --help lists no trace columns: {text}"
    out = []
    for name in re.sub(r"\([^)]*\)", "", listed.group(1)).split(","):
        first, _, last = name.strip().partition("..")
        if last:
            (a, lo, unit), (_, hi, _) = (re.fullmatch(r"([a-z]+)(\d+)(_\w+)", x).groups() for x in (first, last))
            out += [f"{a}{k}{unit}" for k in range(int(lo), int(hi) + 1)]
        else:
            out.append(first)
    return out


def test_run_help_lists_the_columns_a_trace_has(tmp_path):
    """--help says what the trace records: the header of a trace `stiffcomp run --trace` wrote, in its order."""
    cfg = write_config(tmp_path, {"plc": {"port": free_port()}})
    trace = tmp_path / "trace.csv"
    p = subprocess.run(stiffcomp("run", "--config", str(cfg), "--duration", "0.2", "--trace", str(trace)),
                       cwd=ROOT, check=False, capture_output=True, text=True, timeout=120)
    assert p.returncode == 0, p.stderr
    header = trace.read_text().splitlines()[0].split(",")
    shown = subprocess.run(stiffcomp("run", "--help"), cwd=ROOT, check=True, capture_output=True, text=True).stdout
    assert help_trace_columns(shown) == header


def test_duration_counts_from_the_first_cycle(tmp_path):
    """--duration is time spent cycling: the clock starts at the first cycle, not when the start returns (on a
    loaded machine the task's thread starts late; `--duration 0.2` once stopped after 0 cycles), so even
    `--duration 0` runs the cycle and stops it cleanly."""
    cfg = write_config(tmp_path, {"plc": {"port": free_port()}})
    stats = tmp_path / "stats.json"
    p = subprocess.run(stiffcomp("run", "--config", str(cfg), "--duration", "0", "--stats-json", str(stats)),
                       cwd=ROOT, check=False, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    s = json.loads(stats.read_text())
    assert s["cycles"] >= 1 and s["status"] == "stopped"


def test_a_replayed_accelerometer_reaches_the_trace(tmp_path):
    """`stiffcomp run` with ``accelerometer.replay``: every traced cycle after the first (where the count starts,
    as the PLC's does) while the box's samples last carries the sample the file releases at its time since the
    first cycle (untared: |a - g| = |f| in any pose), status bit 8 set; after the file's last sample and
    ``timeout_ms`` the box reads frozen: the bit clear, a zero."""
    t_s = 0.001 * np.arange(500)
    f = np.column_stack([3.0 * np.sin(2.0 * np.pi * 10.0 * t_s), 0.5 * np.cos(2.0 * np.pi * 3.0 * t_s), 0.0 * t_s])
    rows = "".join(f"{t:.3f},{x!r},{y!r},{z!r}\n" for t, (x, y, z) in zip(t_s, f.tolist()))
    (tmp_path / "box.csv").write_text("t_s,acc_x,acc_y,acc_z\n" + rows)
    cfg = write_config(tmp_path, {"plc": {"port": free_port()}, "accelerometer": {
        "enabled": True, "timeout_ms": 20.0, "replay": str(tmp_path / "box.csv")}})
    trace = tmp_path / "trace.csv"
    p = subprocess.run(stiffcomp("run", "--config", str(cfg), "--duration", "1.0", "--trace", str(trace)),
                       cwd=ROOT, check=False, capture_output=True, text=True, timeout=60)
    assert p.returncode == 0, p.stderr
    t = read_trace(trace)
    g = np.asarray(load_config(cfg).gravity.g_mps2)
    acc = np.column_stack([t.column(f"acc_{a}_mps2") for a in "xyz"])
    ok = (t.column("status_word").astype(int) & int(Status.ACCELEROMETER_OK)) != 0
    since = t.time_s - t.time_s[0]
    released = np.searchsorted(t_s, since + 1e-9, side="right") - 1
    # the cycles while the file lasts, the first left out (the count's start), and those after its end and timeout
    during, after = (since > 0.0) & (since < t_s[-1]), since > t_s[-1] + 0.03
    assert during.sum() > 300 and after.sum() > 100, (during.sum(), after.sum())
    assert ok[during].all() and not ok[after].any()
    np.testing.assert_allclose(np.linalg.norm(acc[during] - g, axis=1), np.linalg.norm(f[released[during]], axis=1),
                               atol=2e-5)
    assert np.all(acc[after] == 0.0)
    assert "accelerometer_frozen" in p.stderr
    # the box recorded: each cycle's reading as it came (float32), the count one more where a new one came,
    # and the trace read back as a replay holds the samples the file released, at the cycles that took them
    box = t.block(("box_x_mps2", "box_y_mps2", "box_z_mps2"))
    np.testing.assert_array_equal(box[during], f[released[during]].astype(np.float32))
    new = np.flatnonzero(np.diff(released) > 0) + 1
    np.testing.assert_array_equal(np.flatnonzero(np.diff(t.column("box_samples")) != 0) + 1, new)
    again = BoxReplay(trace)
    np.testing.assert_array_equal(again.t_s[1:], since[new])
    np.testing.assert_array_equal(np.array(again.values[1:]), f[released[new]].astype(np.float32))
