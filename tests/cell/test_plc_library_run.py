"""The generated PLC library, run: its blocks execute (`st_runtime`, on blark's parse of the files
`stiffcomp plc-library` writes) against the service's side of the contract, in simulated time.

The service's side is the process image the Modbus server and the ADS server serve (`ProcessImage.read`,
`ProcessImage.write`: the Modbus rules; `ads.area`: %MB), with a 1 ms cycle that publishes a record and
reads the PLC's block as the service's cycle does (`ProcessImage.publish`, `ProcessImage.inputs`). Each
request of the PLC takes as long as the test's network says; the service handles it halfway through.
"""

from __future__ import annotations

import itertools
import math
import struct
from pathlib import Path

import pytest
import yaml

from cell.plc import Endpoint, generate
from plc_link.ads import ams
from plc_link.ads.area import MB_GROUP, AreaView, Layout
from plc_link.contract import Command, Fault, Status, to_plc
from plc_link.image import ProcessImage
from plc_link.register_map import RegisterMap
from st_runtime import Ended, Runtime, load
from st_runtime.requests import MB_ADDRESS

ROOT = Path(__file__).resolve().parents[2]
SHIPPED_MAP = ROOT / "config" / "registers.yaml"
COMMITTED = ROOT / "cell" / "plc" / "generated" / "twincat"
JOINTS = (10.5, -20.25, 33.3, 0.0123, -179.9, 90.0)              # deg
CORRECTION = (0.0123, -0.0456, 0.5, -1.25, 0.0001, 2.0)         # deg
RUNNING = int(Status.RUNNING | Status.ACTIVE | Status.SENSOR_OK | Status.PLC_SEEN)
PULSE_MS, REQUEST_TIMEOUT_MS = 20, 100                            # GVL_StiffCompSettings' defaults


def scaled_map(tmp_path: Path) -> Path:
    """The shipped map with integer registers and a scale, as docs/register_map.md allows: corrections 1..3
    in INT at 0.01 deg (leaving a reserved word after each), 4..6 in DINT at 0.0001 deg; joints in DINT at
    0.001 deg; plan_time_s bound in DINT at 1 ms."""
    data = yaml.safe_load(SHIPPED_MAP.read_text())
    for r in data["to_plc"]["registers"]:
        if r["name"] in ("correction_q1", "correction_q2", "correction_q3"):
            r.update(type="int16", scale=100)
        elif r["name"].startswith("correction_q"):
            r.update(type="int32", scale=10000)
    regs = data["from_plc"]["registers"]
    for r in regs:
        if r["name"] in {f"q{i}" for i in range(1, 7)}:
            r.update(type="int32", scale=1000)
    regs.append({"name": "plan_time_s", "address": 0x800F, "type": "int32", "scale": 1000})
    path = tmp_path / "scaled.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


ACC_REGISTERS = ({"name": "acc_x", "address": 0x800F, "type": "float32", "unit": "m/s2"},
                 {"name": "acc_y", "address": 0x8011, "type": "float32", "unit": "m/s2"},
                 {"name": "acc_z", "address": 0x8013, "type": "float32", "unit": "m/s2"},
                 {"name": "acc_samples", "address": 0x8015, "type": "uint16"})


def accelerometer_map(tmp_path: Path) -> Path:
    """The shipped map with the accelerometer's four values bound (docs/register_map.md)."""
    data = yaml.safe_load(SHIPPED_MAP.read_text())
    data["from_plc"]["registers"] += [dict(r) for r in ACC_REGISTERS]
    path = tmp_path / "accelerometer.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


class Service:
    """The service's side: the process image, and a 1 ms cycle that reads the PLC's block (counting the rising
    edges of tare and reset, as the service acts on them) and publishes its record."""

    def __init__(self, rmap: RegisterMap):
        self.image = ProcessImage(rmap)
        self.layout = Layout(rmap)
        self.cycles = 0
        self.fault = 0
        self.correction = CORRECTION
        self.edges = {Command.TARE: 0, Command.RESET: 0}
        self.command = 0
        self.plc_heartbeats: set[int] = set()

    def step(self) -> None:
        inputs = self.image.inputs()
        command = int(inputs.command_word)
        for bit in self.edges:
            self.edges[bit] += bool(command & bit and not self.command & bit)
        self.command = command
        self.plc_heartbeats.add(int(inputs.plc_heartbeat))
        self.cycles += 1
        status = RUNNING | (int(Status.FAULTED) if self.fault else 0)
        self.image.publish(to_plc(heartbeat=self.cycles & 0xFFFF, cycle_count=self.cycles, status_word=status,
                                  fault_word=self.fault, task_state=1, cycle_time_us=1000.0,
                                  **{f"correction_q{i + 1}": c for i, c in enumerate(self.correction)}))


class SimTransfer:
    """One request on the test's network: it ends ``took`` ms after it started, and the service handles it then
    (``serve``: what the request does to the service, and the data it brings back); cancelled before, it never
    reaches the service."""

    def __init__(self, serve, now_ms: int, took: int):
        self.serve, self.due, self.result = serve, now_ms + took, None

    def ended(self, now_ms: int) -> Ended | None:
        if self.result is None and self.serve is not None and now_ms >= self.due:
            error, data = self.serve()
            self.result = Ended(error, data, self.due)
        return self.result

    def cancel(self) -> None:
        self.serve = None


class Network:
    """How long each request takes (``durations(kind, now_ms) -> ms``), and what the service answers: Modbus
    through the image's rules (a refused access is TF6250's 16#8002), ADS through its %MB area."""

    def __init__(self, service: Service, durations):
        self.service, self.durations = service, durations
        self.dialled: set[tuple] = set()

    def _transfer(self, kind: str, now_ms: int, serve) -> SimTransfer:
        return SimTransfer(serve, now_ms, self.durations(kind, now_ms))

    def modbus_read(self, host, port, unit, table, address, count, now_ms):
        self.dialled.add((host, port, unit))

        def serve():
            words = self.service.image.read(table, address, count)
            return (MB_ADDRESS, b"") if words is None else (0, struct.pack(f"<{count}H", *words))
        return self._transfer("read", now_ms, serve)

    def modbus_write(self, host, port, unit, address, words, now_ms):
        self.dialled.add((host, port, unit))
        return self._transfer("write", now_ms, lambda: (0 if self.service.image.write("holding_registers", address,
                                                                                       words) else MB_ADDRESS, b""))

    def ads_read(self, net_id, port, group, offset, length, now_ms):
        def serve():
            return AreaView(self.service.layout, self.service.image.snapshot()).read(group, offset, length)
        return self._transfer("read", now_ms, serve)

    def ads_write(self, net_id, port, group, offset, data, now_ms):
        def serve():
            if group != MB_GROUP:
                return ams.ADSERR_INVALID_GROUP, b""
            return self.service.layout.write(self.service.image, offset, data), b""
        return self._transfer("write", now_ms, serve)


@pytest.fixture(scope="module")
def libraries(tmp_path_factory) -> dict[str, tuple[RegisterMap, list[Path]]]:
    """The shipped library (the committed files) and one generated for the scaled map (the Modbus block)."""
    folder = tmp_path_factory.mktemp("scaled")
    rmap = RegisterMap.from_yaml(scaled_map(tmp_path_factory.mktemp("map")))
    for rel, data in generate(rmap, Endpoint(), ("twincat",)).items():
        (folder / Path(rel).name).write_bytes(data)
    files = [p for p in folder.iterdir() if p.stem not in ("FB_StiffComp", "MAIN")]
    acc_folder = tmp_path_factory.mktemp("accelerometer")
    acc_map = RegisterMap.from_yaml(accelerometer_map(tmp_path_factory.mktemp("acc_map")))
    for rel, data in generate(acc_map, Endpoint(), ("twincat",)).items():
        (acc_folder / Path(rel).name).write_bytes(data)
    return {"shipped": (RegisterMap.from_yaml(SHIPPED_MAP), sorted(COMMITTED.iterdir())), "scaled": (rmap, files),
            "accelerometer": (acc_map, sorted(acc_folder.iterdir()))}


class Cell:
    """One block on one service, stepped a millisecond at a time: the service's cycle, then the PLC's."""

    def __init__(self, libraries, which: str, block: str, durations, task: str | None = None,
                 service_map: RegisterMap | None = None):
        rmap, files = libraries[which]
        self.rmap = rmap
        self.service = Service(service_map or rmap)
        self.runtime = Runtime(Network(self.service, durations))
        self.machine = load(files, self.runtime)
        self.program = self.machine.instance(task or block)
        self.fb = getattr(self.program, "fbStiffComp", self.program)
        self.fb.bEnable = True
        self.fb.aJointsDeg[:] = [self.machine.namespace["f32"](q) for q in JOINTS]

    def run(self, ms: int, each=None) -> None:
        for _ in range(ms):
            self.service.step()
            if each is not None:
                each(self.runtime.now_ms)
            self.program.body()
            self.runtime.now_ms += 1

    def close(self) -> None:
        self.service.image.close()


@pytest.fixture
def cells():
    made: list[Cell] = []
    yield made
    for c in made:
        c.close()


def resolution(r) -> float:
    """Half a step of register ``r``: what scaling may cost; a REAL's rounding for a float32 register."""
    return 0.5 / r.scale if r.type != "float32" else 0.0


def fixed(ms: int):
    return lambda kind, now: ms


BLOCKS = [("shipped", "FB_StiffCompModbus"), ("shipped", "FB_StiffComp"), ("scaled", "FB_StiffCompModbus")]


@pytest.mark.parametrize(("which", "block"), BLOCKS)
def test_joints_heartbeat_and_correction_cross_as_the_map_scales_them(libraries, cells, which, block):
    cell = Cell(libraries, which, block, fixed(5))
    cells.append(cell)
    cell.run(200)
    fb, got, rmap = cell.fb, cell.service.image.inputs(), cell.rmap
    assert fb.bAlive and fb.bValid and not fb.bError
    for i, q in enumerate(JOINTS, 1):               # the service's registers, decoded as the map scales them
        r = rmap.by_name[f"q{i}"]
        assert abs(getattr(got, f"q{i}") - q) <= resolution(r) + 1e-6 * abs(q), (r.name, getattr(got, f"q{i}"))
    for i, c in enumerate(CORRECTION, 1):           # the block's output, in degrees
        r = rmap.by_name[f"correction_q{i}"]
        assert abs(fb.aCorrectionDeg[i - 1] - c) <= resolution(r) + 1e-6 * abs(c), (r.name, fb.aCorrectionDeg)
    r1 = rmap.by_name["correction_q1"]
    assert abs(fb.aCorrectionDeg[0] - 0.0123) <= max(resolution(r1), 1e-7)      # 0.0123 deg reads 0.0123 deg
    # the PLC's heartbeat (+1 each PLC cycle) reaches the service anew with every write (one each 5 + 1 ms)
    assert len(cell.service.plc_heartbeats) >= 200 // 6 - 2
    assert int(got.command_word) == int(Command.ENABLE)


def test_the_scaled_map_is_not_copied_raw(libraries, cells):
    """What the issue saw: copied unscaled, the corrections arrive x100 and the joints /1000."""
    cell = Cell(libraries, "scaled", "FB_StiffCompModbus", fixed(5))
    cells.append(cell)
    cell.fb.fPlanTimeS = 12.345
    cell.run(100)
    assert cell.rmap.by_name["correction_q1"].scale == 100 and cell.rmap.by_name["q1"].scale == 1000
    assert math.isclose(cell.fb.aCorrectionDeg[2], 0.5, rel_tol=1e-6)
    assert math.isclose(cell.service.image.inputs().q1, 10.5, rel_tol=1e-6)
    assert abs(cell.service.image.inputs().plan_time_s - 12.345) <= 0.0005
    assert cell.fb.stToPlc.correction_q3 == 50                                   # the raw register: 0.5 * 100


def pulse_period(delay_ms: int) -> int:
    """Time between two edges a pulse needs at most: a phase waits for the write in flight, then one loaded in
    it (two requests and a cycle between), and lasts tPulse at least; a pulse is a set and a clear phase."""
    return max(4 * (delay_ms + 2), 2 * PULSE_MS) + 10


EDGES = 61


@pytest.mark.parametrize("delay_ms", [5, 20, 30, 45])
@pytest.mark.parametrize(("which", "block"), BLOCKS)
def test_no_tare_or_reset_pulse_is_lost_however_long_the_writes_take(libraries, cells, which, block, delay_ms):
    cell = Cell(libraries, which, block, fixed(delay_ms))
    cells.append(cell)
    period, alive = pulse_period(delay_ms), []

    def press(now: int) -> None:             # each input high for 10 ms, tare and reset half a period apart
        k, phase = divmod(now, period)
        cell.fb.bTare = k < EDGES and phase < 10
        cell.fb.bReset = k < EDGES and period // 2 <= phase < period // 2 + 10
        if now > 4 * delay_ms:
            alive.append(cell.fb.bAlive and cell.fb.bValid)

    cell.run(EDGES * period + 4 * period, press)
    assert cell.service.edges == {Command.TARE: EDGES, Command.RESET: EDGES}
    assert all(alive), f"bAlive or bValid dropped in {alive.count(False)} cycles"


def test_edges_faster_than_the_writes_merge_into_one_more_pulse_never_none(libraries, cells):
    """An edge while a pulse is delivered gives one more pulse after it: a burst is not lost, and not repeated."""
    cell = Cell(libraries, "shipped", "FB_StiffCompModbus", fixed(30))
    cells.append(cell)
    burst = {100, 110, 120, 130}                    # four edges within one delivery

    def press(now: int) -> None:
        cell.fb.bTare = any(t <= now < t + 5 for t in burst)

    cell.run(1000, press)
    assert cell.service.edges[Command.TARE] == 2


def test_one_slow_request_does_not_drop_balive(libraries, cells):
    """One request of 60 ms (each way) amid 5 ms ones: the timeouts hold together, so bAlive holds."""
    slow = {}

    def durations(kind: str, now: int) -> int:
        if now >= 200 and kind not in slow:
            slow[kind] = now
            return 60
        return 5

    cell = Cell(libraries, "shipped", "FB_StiffCompModbus", durations)
    cells.append(cell)
    seen = []
    cell.run(500, lambda now: seen.append((now, cell.fb.bAlive)))
    assert set(slow) == {"read", "write"}
    assert all(alive for now, alive in seen if now > 20), [now for now, alive in seen if now > 20 and not alive][:5]
    assert not cell.fb.bError


def test_a_request_past_its_timeout_drops_balive_until_the_next_good_read(libraries, cells):
    """The other side of the same timeouts: a read that takes longer than tRequestTimeout fails, and bAlive
    drops (not a test of luck: without it the check above would hold for any timeout)."""
    slow = []

    def durations(kind: str, now: int) -> int:
        if kind == "read" and now >= 200 and not slow:
            slow.append(now)
            return REQUEST_TIMEOUT_MS + 50
        return 5

    cell = Cell(libraries, "shipped", "FB_StiffCompModbus", durations)
    cells.append(cell)
    seen = {}
    cell.run(500, lambda now: seen.__setitem__(now, (cell.fb.bAlive, cell.fb.bError)))
    failed = [now for now, (alive, error) in seen.items() if error]
    assert failed and all(not seen[now][0] for now in failed)
    assert seen[499] == (True, False)


@pytest.mark.parametrize(("which", "block"), BLOCKS)
def test_a_fault_clears_bvalid_and_the_correction(libraries, cells, which, block):
    cell = Cell(libraries, which, block, fixed(20))
    cells.append(cell)
    cell.run(200)
    assert cell.fb.bValid and cell.fb.aCorrectionDeg[2] == pytest.approx(0.5)
    cell.service.fault = int(Fault.SENSOR_TIMEOUT)
    cell.run(60)
    assert not cell.fb.bValid and cell.fb.aCorrectionDeg == [0.0] * 6
    assert cell.fb.stFaults.bSensorTimeout and cell.fb.stStatus.bFaulted and cell.fb.bAlive
    assert cell.fb.nFaultWord == int(Fault.SENSOR_TIMEOUT)
    cell.service.fault = 0
    cell.run(60)
    assert cell.fb.bValid and cell.fb.aCorrectionDeg[2] == pytest.approx(0.5)


def test_a_service_that_stops_moving_drops_balive_after_tservicetimeout(libraries, cells):
    cell = Cell(libraries, "shipped", "FB_StiffCompModbus", fixed(5))
    cells.append(cell)
    cell.run(100)
    assert cell.fb.bAlive
    cell.service.step = lambda: None                # the service's cycle stands still; the image still answers
    seen = []
    cell.run(300, lambda now: seen.append(cell.fb.bAlive))
    assert not seen[-1] and not cell.fb.bValid
    assert 150 - 10 <= seen.index(False) <= 150 + 15          # tServiceTimeout after the last move


@pytest.mark.parametrize("cycle_ms", [1, 4])
def test_main_steps_by_its_tasks_cycle_time(libraries, cells, cycle_ms):
    """MAIN rate-limits the correction by fMaxRateDegPerS x the task's own cycle time (its task info)."""
    rmap, files = libraries["shipped"]
    service = Service(rmap)
    runtime = Runtime(Network(service, fixed(5)), cycle_ms=cycle_ms)
    machine = load(files, runtime)
    main = machine.instance("MAIN")
    main.bEnable = True

    class Run:
        def close(self):
            service.image.close()
    cells.append(Run())
    applied = []
    for _ in range(400 // cycle_ms):
        for _ in range(cycle_ms):
            service.step()
        main.body()
        runtime.now_ms += cycle_ms
        applied.append(main.aAppliedDeg[5])
    assert main.fCycleTimeS == pytest.approx(cycle_ms / 1000)
    steps = [b - a for a, b in itertools.pairwise(applied)]
    assert max(steps) == pytest.approx(2.0 * cycle_ms / 1000, rel=1e-5)     # fMaxRateDegPerS := 2.0
    assert applied[-1] <= CORRECTION[5]


def test_writes_the_service_refuses_are_errors_and_hold_the_bit(libraries, cells):
    """A library made for another map (the scaled one writes plan_time_s, where the shipped map has no
    register): each write is refused (ILLEGAL_ADDRESS, TF6250's nErrId 16#8002), bError says so, and a tare
    stays asked for rather than counted as sent."""
    cell = Cell(libraries, "scaled", "FB_StiffCompModbus", fixed(5), service_map=libraries["shipped"][0])
    cells.append(cell)
    cell.run(300, lambda now: setattr(cell.fb, "bTare", 100 <= now < 110))
    assert cell.fb.bError and cell.fb.nErrorId == 0x8002
    assert cell.service.edges[Command.TARE] == 0 and cell.fb.fbTare.bBusy
    assert cell.service.image.refused_writes > 40


def test_the_accelerometers_new_valid_samples_cross_scaled_and_counted(libraries, cells):
    """MAIN's box inputs (linked AT %I* to the EP3751's process data) reach the service: each new value (its
    toggle inverted) scaled from mg per LSB to m/s^2 and counted; a value the box marks invalid (TxPDO State, a
    self test) neither counted nor passed; a toggle that stands still counts nothing (a frozen box)."""
    cell = Cell(libraries, "accelerometer", "FB_StiffComp", fixed(1), task="MAIN")
    cells.append(cell)
    main, f32 = cell.program, cell.machine.namespace["f32"]
    counts = {"nAccX": 120, "nAccY": -1000, "nAccZ": 1000}        # mg: gravity along z
    sent: list[tuple[int, ...]] = []
    during_test: list[float] = []

    def box(now_ms: int) -> None:
        if now_ms == 59:
            during_test.append(cell.service.image.inputs().acc_x)
        if now_ms < 100:                        # a new value every 2 ms
            if now_ms % 2 == 0:
                main.bAccToggle = not main.bAccToggle
                for k, name in enumerate(counts):
                    setattr(main, name, counts[name] + now_ms * (k + 1))
                sent.append(tuple(getattr(main, n) for n in counts))
            main.bAccStateY = 40 <= now_ms < 60     # a self test: 10 values invalid

    cell.run(100, box)
    cell.run(20)                                # the box frozen
    got = cell.service.image.inputs()
    valid = [v for k, v in enumerate(sent) if not 40 <= 2 * k < 60]
    assert int(got.acc_samples) == len(valid) == 40
    scale = f32(0.00980665)
    last = valid[-1]
    for axis, count in zip("xyz", last):
        assert getattr(got, f"acc_{axis}") == f32(f32(count) * scale), axis
    assert during_test == [f32(f32(sent[19][0]) * scale)]     # the last valid value (38 ms) held through the test


def test_a_map_that_binds_part_of_the_accelerometer_is_refused(tmp_path):
    from plc_link.errors import RegisterMapError

    data = yaml.safe_load(SHIPPED_MAP.read_text())
    data["from_plc"]["registers"] += [dict(r) for r in ACC_REGISTERS[:3]]
    path = tmp_path / "part.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(RegisterMapError, match="binds acc_x, acc_y, acc_z but not acc_samples"):
        generate(RegisterMap.from_yaml(path), Endpoint(), ("twincat",))
