"""The HIL's virtual PLC runs the TwinCAT program the cell loads (`hil.virtual_plc`, `st_runtime`): what the
retired Python twin was tested for, now asked of the generated library itself, through the cell's network
(`hil.cell_network.ImageNetwork`) against a service's process image whose records the test publishes.

Each test plays the service's side one PLC cycle at a time; the program's clock is the cycle's program time."""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from hil.cell_network import ImageNetwork, PlcFaults
from hil.circle import run_circle
from hil.errors import HilError
from hil.plc_program import PlcProgram, generate_program
from hil.virtual_plc import VirtualPlc
from plc_link.contract import Command, Fault, Status, to_plc
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from testlib.hil import ROOT, scenario

RMAP = RegisterMap.from_yaml(ROOT / "config" / "registers.yaml")
Q_REF = [10.0, -60.0, 90.0, 0.0, 60.0, 0.0]
DT = 0.004
RUNNING = int(Status.RUNNING | Status.ACTIVE | Status.SENSOR_OK | Status.PLC_SEEN)


@pytest.fixture(scope="module")
def program(tmp_path_factory) -> PlcProgram:
    return generate_program(RMAP, 502, 1, tmp_path_factory.mktemp("plc"))


class Cell:
    """The program on an image; ``serve(k)`` publishes the service's record of PLC cycle k (or nothing)."""

    def __init__(self, program: PlcProgram, compensate: bool = True, faults: PlcFaults | None = None,
                 settings: dict | None = None):
        self.image = ProcessImage(RMAP)
        self.network = ImageNetwork(self.image, RMAP, faults)
        self.plc = VirtualPlc(program, self.network, RMAP, lambda t: Q_REF, compensate, DT, settings=settings)
        self.plc.new_log(4000)
        self.k = 0

    def publish(self, correction=(0.0,) * 6, fault: int = 0, moving: bool = True, down: bool = False) -> None:
        """The service's record: its correction only while the PLC enables it, as the service does."""
        n = self.k if moving else 0
        if not self.command & Command.ENABLE:
            correction = (0.0,) * 6
        self.image.publish(to_plc(heartbeat=n & 0xFFFF, cycle_count=n, status_word=RUNNING | (Status.FAULTED if
                                  fault else 0), fault_word=fault,
                                  **{f"correction_q{i + 1}": c for i, c in enumerate(correction)}))

    def step(self, n: int = 1, **service) -> list[float]:
        for _ in range(n):
            if service.get("down"):
                self.network.faults = PlcFaults(drop_at=0.0, drop_for_s=math.inf)
            else:
                self.network.faults = PlcFaults()
                self.publish(**service)
            q = self.plc.cycle(self.k * DT)
            self.k += 1
        return q

    @property
    def command(self) -> int:
        return int(self.image.inputs().command_word)

    def close(self) -> None:
        self.image.close()


@pytest.fixture
def cell(program):
    made = []

    def make(**kw) -> Cell:
        made.append(Cell(program, **kw))
        return made[-1]
    yield make
    for c in made:
        c.close()


def test_without_the_service_the_robot_follows_its_references(cell):
    c = cell()
    for _ in range(50):
        assert c.step(down=True) == pytest.approx(Q_REF, abs=1e-5)
    assert not c.plc.fb.bAlive and c.plc.fb.bError and c.plc.fb.nErrorId == 0x8007274D     # WSAECONNREFUSED


def test_the_correction_is_rate_limited_on_and_ramps_off_when_the_service_stands_still(cell):
    c, corr = cell(), [0.05, -0.02, 0.01, 0.0, 0.0, 0.0]
    applied = []
    for _ in range(100):
        c.step(correction=corr)
        applied.append(np.array(c.plc.main.aAppliedDeg))
    steps = np.abs(np.diff(applied, axis=0))
    assert steps.max() <= 2.0 * DT * (1 + 1e-5) and steps.max() > 0.9 * 2.0 * DT        # MAIN's 2 deg/s
    np.testing.assert_allclose(applied[-1], corr, atol=1e-6)
    for _ in range(100):                                   # heartbeat and cycle count stand still
        c.step(correction=corr, moving=False)
    assert not c.plc.fb.bAlive and list(c.plc.main.aAppliedDeg) == [0.0] * 6
    assert c.step(correction=corr, moving=False) == pytest.approx(Q_REF, abs=1e-5)


@pytest.mark.parametrize("timeout_ms", [None, 60.0])
def test_the_link_is_lost_after_the_programs_timeout_or_the_scenarios(cell, timeout_ms):
    """Without a scenario value the program's own tServiceTimeout (150 ms) holds; with one, it is written in."""
    c = cell(settings={"service_timeout_ms": timeout_ms, "max_rate_deg_s": None})
    c.step(20)
    alive = []
    for _ in range(100):
        c.step(moving=False)
        alive.append(c.plc.fb.bAlive)
    lost_ms = alive.index(False) * DT * 1000.0
    assert (timeout_ms or 150.0) <= lost_ms <= (timeout_ms or 150.0) + 3 * DT * 1000.0, lost_ms


def test_reset_is_asked_on_first_contact_and_after_a_loss_and_reaches_the_service(cell):
    c = cell()
    resets = []
    for k in range(300):
        c.step(down=100 <= k < 150)
        resets.append(bool(c.command & Command.RESET))
    rising = [k for k in range(1, 300) if resets[k] and not resets[k - 1]]
    assert len(rising) == 2 and rising[0] < 10 and 150 <= rising[1] < 165, rising


def test_uncompensated_neither_enables_nor_applies(cell):
    c = cell(compensate=False)
    for _ in range(60):
        q = c.step(correction=[0.1] * 6)
    assert c.command & Command.ENABLE == 0 and q == pytest.approx(Q_REF, abs=1e-5)


def test_a_frozen_heartbeat_is_the_transports_and_the_service_sees_it_stand_still(cell):
    c = cell(faults=None)
    seen = []
    for k in range(120):
        c.network.faults = PlcFaults(heartbeat_stop_at=0.2)
        c.publish()
        c.plc.cycle(c.k * DT)
        c.k += 1
        seen.append(int(c.image.inputs().plc_heartbeat))
    before, after = seen[:45], seen[60:]
    assert len(set(before)) > 15 and len(set(after)) == 1


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
def test_a_non_finite_correction_never_reaches_the_command(cell, bad):
    """The service's correction register corrupted: the program refuses it (bValid FALSE) and ramps to zero."""
    c = cell()
    c.step(100, correction=[0.05] * 6)
    assert c.plc.fb.bValid
    commands = [c.step(correction=[0.05, bad, 0.05, 0.05, 0.05, 0.05]) for _ in range(100)]
    assert np.isfinite(commands).all()
    assert not c.plc.fb.bValid
    assert list(c.plc.main.aAppliedDeg) == [0.0] * 6


def test_a_fault_word_clears_the_correction(cell):
    c = cell()
    c.step(100, correction=[0.05] * 6)
    c.step(100, correction=[0.05] * 6, fault=int(Fault.SENSOR_TIMEOUT))
    assert c.plc.fb.bAlive and not c.plc.fb.bValid and list(c.plc.main.aAppliedDeg) == [0.0] * 6


def test_a_program_without_the_names_the_plc_binds_is_refused_naming_them(program, tmp_path):
    shutil.copytree(program.folder, tmp_path / "p")
    main = tmp_path / "p" / "MAIN.TcPOU"
    main.write_text(main.read_text().replace("aCommandDeg", "aOutDeg"))
    with pytest.raises(HilError, match="MAIN has no aCommandDeg"):
        Cell(PlcProgram(tmp_path / "p"))
    with pytest.raises(HilError, match="no TwinCAT sources"):
        PlcProgram(tmp_path)


def uncorrected(folder: Path, into: Path) -> Path:
    """The program with MAIN's addition of the applied correction to the references removed."""
    shutil.copytree(folder, into)
    main = into / "MAIN.TcPOU"
    text = main.read_text()
    assert "aCommandDeg[i] := aReferenceDeg[i] + aAppliedDeg[i];" in text
    main.write_text(text.replace("aCommandDeg[i] := aReferenceDeg[i] + aAppliedDeg[i];",
                                 "aCommandDeg[i] := aReferenceDeg[i];"))
    return into


def test_the_circle_runs_the_program_given_and_an_edited_main_cuts_uncompensated(program, tmp_path):
    """`--plc-program DIR`: the generated program cuts compensated; with MAIN no longer adding the correction,
    the same pass cuts as the uncompensated one. The summary names the files it ran."""
    sc = scenario(60.0)
    made = run_circle(sc, lockstep=True, workdir=tmp_path / "gen").summary
    edited = uncorrected(program.folder, tmp_path / "edited")
    cut = run_circle(sc, lockstep=True, workdir=tmp_path / "edit", plc_program=edited).summary
    assert made["mean_error_mm"] < 0.1 * made["mean_error_mm_uncompensated"]
    assert cut["mean_error_mm"] == pytest.approx(cut["mean_error_mm_uncompensated"], rel=0.02)
    assert cut["plc_program"]["folder"] == str(edited)
    assert set(cut["plc_program"]["files"]) == {p.name for p in edited.iterdir()}


@pytest.mark.realtime
def test_in_real_time_an_edited_main_cuts_uncompensated_and_the_summary_names_it(program, tmp_path):
    """The same through the processes: the virtual PLC's process loads the edited program and the service
    compensates in vain (its correction reaches no axis)."""
    edited = uncorrected(program.folder, tmp_path / "edited")
    res = run_circle(scenario(60.0), workdir=tmp_path / "rt", plc_program=edited)
    s, log = res.summary, res.passes["compensated"].log
    assert np.abs(log.q_cmd - log.q_ref).max() == 0.0          # no correction reached an axis, any cycle
    # the path error is the uncompensated pass's but for real time's jitter (2.5 % apart with both cores busy)
    assert s["mean_error_mm"] == pytest.approx(s["mean_error_mm_uncompensated"], rel=0.05)
    assert s["plc_program"]["files"]["MAIN.TcPOU"] != program.summary()["files"]["MAIN.TcPOU"]
    assert s["plc_program"]["dialled"] == ["Modbus 127.0.0.1:502 unit 1"]


def test_the_committed_library_with_its_ads_main_cuts_compensated_in_lock_step(tmp_path):
    """plc/ as the cell loads it (MAIN calls FB_StiffComp: ADSREAD and ADSWRITE against the service's %MB area)."""
    s = run_circle(scenario(60.0), lockstep=True, workdir=tmp_path, plc_program=ROOT / "cell" / "plc" / "generated").summary
    assert s["mean_error_mm"] < 0.1 * s["mean_error_mm_uncompensated"], s
    assert s["plc_program"]["folder"] == str(ROOT / "cell" / "plc" / "generated" / "twincat")
    assert s["plc_program"]["dialled"] == ["ADS 127.0.0.1.1.1 port 851"], s["plc_program"]


@pytest.mark.realtime
def test_in_real_time_the_committed_library_reaches_the_service_over_ads(tmp_path):
    """The same through the processes: the program's ADS requests go to the service's ADS server over AMS/TCP."""
    s = run_circle(scenario(60.0), workdir=tmp_path, plc_program=ROOT / "cell" / "plc" / "generated").summary
    assert s["mean_error_mm"] < 0.1 * s["mean_error_mm_uncompensated"], s
    assert s["plc_program"]["dialled"] == ["ADS 127.0.0.1.1.1 port 851"], s["plc_program"]
