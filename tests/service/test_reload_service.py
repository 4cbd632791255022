"""Reload without a restart, against the running service (`stiffcomp run` in a child process, one for
the module), driven by `stiffcomp reload` and read as the PLC reads it (Modbus, and pyads by handle).

The service replays a constant load with noise and corrects without a PLC (``plc.enable_on_start``);
each test rewrites the config file from the same base plus its own changes, then reloads.
"""

from __future__ import annotations

import contextlib
import copy
import io
import threading
import time

import numpy as np
import pyads
import pytest
from pymodbus.client import ModbusTcpClient

from hil.run import ServiceProcess
from hil.testing import ROOT, free_port, scaled_model_file, write_config
from plc_link.register_map import RegisterMap
from service.config import load_config
from service.sources.replay import write_log
from stiffness.files.yaml_schema import deep_update, dump_yaml, read_yaml
from tools.cli import main

pytestmark = pytest.mark.realtime

CODEC = RegisterMap.from_yaml(ROOT / "config" / "registers.yaml").codecs["to_plc"]
LOAD = np.array([300.0, -200.0, 400.0, 15.0, 10.0, 5.0])
NOISE = np.array([2.0, 2.0, 2.0, 0.2, 0.2, 0.2])
FORCES = ["wrench_fx", "wrench_fy", "wrench_fz"]


class Service:
    def __init__(self, tmp, monkeypatch):
        monkeypatch.setenv("STIFFCOMP_RUN_DIR", str(tmp / "run"))       # the child inherits it
        log = tmp / "ft.blf"
        write_log(log, LOAD + NOISE * np.random.default_rng(3).standard_normal((5000, 6)))
        self.port = free_port()
        self.path = write_config(tmp, {
            "source": {"replay": {"file": str(log), "pacing": "realtime", "loop": True}},
            "gravity": {"tool": {"mass_kg": 0.0}, "bias": [0.0] * 6}, "plc": {"port": self.port, "enable_on_start": True},
            "limits": {"fault_ramp_s": 1.0}, "cycle": {"realtime_priority": 0}})
        self.base = read_yaml(self.path)
        self.cfg = load_config(self.path)
        self.proc = ServiceProcess(self.path, tmp)
        self.proc.wait_running(60)
        self.client = ModbusTcpClient("127.0.0.1", port=self.port, timeout=1.0, retries=1)
        assert self.client.connect()

    def read(self) -> dict[str, float]:
        r = self.client.read_input_registers(CODEC.start, count=CODEC.words)
        assert not r.isError(), r
        return dict(zip(CODEC.names, CODEC.decode(r.registers)))

    def log(self) -> str:
        return self.proc.log_path.read_text()

    def reload(self, changes: dict) -> tuple[int, str, list[str]]:
        """The base config with ``changes`` written, then `stiffcomp reload`: (exit code, what it printed,
        the log lines written meanwhile)."""
        data = deep_update(copy.deepcopy(self.base), changes)
        self.path.write_text(dump_yaml(data, sort_keys=False))
        before = len(self.log().splitlines())
        out = io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
            code = main(["reload", "--config", str(self.path)])
        return code, out.getvalue(), self.log().splitlines()[before:]

    def close(self) -> None:
        self.client.close()
        self.proc.stop()


@pytest.fixture(scope="module")
def svc(tmp_path_factory):
    with pytest.MonkeyPatch.context() as mp:
        s = Service(tmp_path_factory.mktemp("reload"), mp)
        try:
            yield s
        finally:
            s.close()


class Recorder:
    """Reads the to_plc block as fast as Modbus answers, in a thread, until stopped."""

    def __init__(self, svc: Service):
        self.rows: list[dict[str, float]] = []
        self._stop = threading.Event()
        self._client = ModbusTcpClient("127.0.0.1", port=svc.port, timeout=1.0, retries=1)
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def _run(self) -> None:
        self._client.connect()
        while not self._stop.is_set():
            r = self._client.read_input_registers(CODEC.start, count=CODEC.words)
            if not r.isError():
                self.rows.append(dict(zip(CODEC.names, CODEC.decode(r.registers))))

    def wait_rows(self, n: int, timeout: float = 30.0) -> None:
        deadline = time.monotonic() + timeout
        start = len(self.rows)
        while len(self.rows) < start + n and time.monotonic() < deadline:
            time.sleep(0.01)

    def stop(self) -> list[dict[str, float]]:
        self._stop.set()
        self._thread.join(10)
        self._client.close()
        return self.rows


def change_over(w: np.ndarray, cycles: np.ndarray, gap: int) -> np.ndarray:
    """Per column, the largest change between two reads at least ``gap`` cycles apart (each read paired with
    the first read that far after it); every pair when none is that far apart. Reads come as fast as Modbus
    answers, so a reload that stalls the reader spans more cycles than the reads before it: the filtered
    noise it may show grows with the span, until the samples are independent."""
    j = np.searchsorted(cycles, cycles + gap)
    pairs = j < len(cycles)
    if not pairs.any():
        return w.max(axis=0) - w.min(axis=0)
    return np.abs(w[j[pairs]] - w[pairs]).max(axis=0)


def reload_lines(lines: list[str]) -> list[str]:
    return [line for line in lines if "reload " in line]


def test_a_reload_with_a_new_cutoff_shows_no_step_in_the_filtered_wrench(svc):
    rec = Recorder(svc)
    rec.wait_rows(300)
    code, out, lines = svc.reload({"filter": {"cutoff_hz": 20.0, "order": 4}})
    rec.wait_rows(300)
    rows = rec.stop()
    assert code == 0, out
    assert "filter.cutoff_hz 100.0 → 20.0" in out and "filter.order 2 → 4" in out
    k = next(i for i, r in enumerate(rows) if r["reload_count"] > rows[0]["reload_count"])
    w = np.array([[r[f] for f in FORCES] for r in rows])
    cycles = np.array([r["cycle_count"] for r in rows])
    gap = cycles[k] - cycles[k - 1]                         # the reads around the reload span this many cycles
    noise = change_over(w[:k], cycles[:k], gap)             # the filtered noise's change over as many cycles before
    assert np.all(np.abs(w[k] - w[k - 1]) <= 1.5 * noise), (gap, w[k - 1], w[k], noise)
    assert np.abs(LOAD[:3]).min() > 20 * noise.max()        # a filter restarted at zero would step by the load
    assert len(reload_lines(lines)) == 1


def test_an_invalid_reload_keeps_the_old_parameters_and_logs_the_key(svc):
    code, _, _ = svc.reload({"filter": {"cutoff_hz": 30.0}})
    assert code == 0
    count = svc.read()["reload_count"]
    code, out, lines = svc.reload({"filter": {"cutoff_hz": 900.0}})
    assert code == 1 and "filter.cutoff_hz = 900" in out
    (line,) = reload_lines(lines)
    assert "refused" in line and "filter.cutoff_hz = 900" in line and str(svc.path) in line and "500" in line
    assert svc.read()["reload_count"] == count
    code, out, _ = svc.reload({"filter": {"cutoff_hz": 40.0}})      # 30 was kept: it is the old value now
    assert code == 0 and "filter.cutoff_hz 30.0 → 40.0" in out


def test_every_accepted_reload_logs_one_line_naming_what_changed(svc):
    for rate in (4.0, 3.0):
        count = svc.read()["reload_count"]
        code, out, lines = svc.reload({"limits": {"max_rate_deg_s": rate}})
        assert code == 0, out
        (line,) = reload_lines(lines)
        assert "accepted" in line and f"limits.max_rate_deg_s [{5.0 if rate == 4.0 else 4.0}" in line
        assert f"→ [{rate}" in line
        assert svc.read()["reload_count"] == count + 1


def test_a_reload_that_changes_a_port_is_refused_by_name(svc):
    count = svc.read()["reload_count"]
    code, out, lines = svc.reload({"plc": {"port": free_port()}, "limits": {"max_rate_deg_s": 2.0}})
    assert code == 1 and "plc.port" in out and "restart" in out
    (line,) = reload_lines(lines)
    assert "refused" in line and "plc.port" in line
    assert svc.read()["reload_count"] == count          # still served on the old port, nothing applied


def test_a_pyads_client_reading_by_handle_keeps_working_across_a_reload(svc):
    a = svc.cfg.ads
    conn = pyads.Connection(a.net_id, a.ams_port, f"127.0.0.1:{a.port}")
    conn.open()
    try:
        version = conn.read(0xF008, 0, pyads.PLCTYPE_BYTE)
        handles = {n: conn.get_handle(f"GVL_Comp.{n}") for n in ("reload_count", "wrench_fz")}
        count = conn.read_by_name("", pyads.PLCTYPE_UINT, handle=handles["reload_count"])
        code, out, _ = svc.reload({"filter": {"cutoff_hz": 50.0}})
        assert code == 0, out
        assert conn.read_by_name("", pyads.PLCTYPE_UINT, handle=handles["reload_count"]) == count + 1
        fz = conn.read_by_name("", pyads.PLCTYPE_REAL, handle=handles["wrench_fz"])
        assert fz == pytest.approx(svc.read()["wrench_fz"], abs=20 * NOISE[2])
        assert conn.read(0xF008, 0, pyads.PLCTYPE_BYTE) == version      # the same symbols, the same version
        for h in handles.values():
            conn.release_handle(h)
    finally:
        conn.close()


def model_file(svc: Service, factor: float, extra: list | None = None) -> str:
    return str(scaled_model_file(svc.cfg.resolve(svc.cfg.model.file), factor,
                                 svc.path.parent / f"model_{factor:g}_{len(extra or [])}.yaml", extra))


def test_a_same_structure_model_ramps_and_another_structure_is_refused(svc):
    extra = [{"effect": "backlash", "joint": 3, "lost_motion_deg": 0.01, "width_Nm": 30.0}]
    code, out, _ = svc.reload({"model": {"file": model_file(svc, 1.0, extra)}})
    assert code == 1 and "model.file:effects" in out and "restart" in out
    rec = Recorder(svc)
    rec.wait_rows(200)
    code, out, _ = svc.reload({"model": {"file": model_file(svc, 2.0)}})
    assert code == 0 and "model.file:joint_spring@joint1" in out, out      # the ramp: fault_ramp_s = 1 s
    start = rec.rows[-1]["cycle_count"]
    deadline = time.monotonic() + 30
    while rec.rows[-1]["cycle_count"] < start + 1500 and time.monotonic() < deadline:
        time.sleep(0.05)
    rows = rec.stop()
    d = np.array([r["deflection_dz"] for r in rows])
    k = next(i for i, r in enumerate(rows) if r["reload_count"] > rows[0]["reload_count"])
    old, new = d[:k].mean(), d[-20:].mean()
    assert new == pytest.approx(2.0 * old, rel=0.05)
    between = [v for v in d[k:] if min(old, new) + 0.2 * abs(new - old) < v < max(old, new) - 0.2 * abs(new - old)]
    assert len(between) >= 5                               # seen on its way, not as a jump
    cycles = np.array([r["cycle_count"] for r in rows])
    corr = np.array([[r[f"correction_q{j}"] for j in range(1, 7)] for r in rows])
    rate = svc.cfg.limits.max_rate_deg_s[0] * 2 * svc.cfg.cycle.period_ms / 1000.0     # at most two periods a step
    steps = np.abs(np.diff(corr, axis=0)).max(axis=1)
    assert np.all(steps <= rate * np.maximum(np.diff(cycles), 1) + 1e-5)
