"""The generated library refuses a correction that is not finite, and nothing a service's registers can hold
stops it: run as `test_plc_library_run` runs it (its `Cell`, `Service` and `Network`), on the service's real
process image, in simulated time.

A NaN or an infinity in a ``float32`` correction register makes ``bValid`` FALSE and ``bCorrectionInvalid``
TRUE, and ``aCorrectionDeg`` zero, so MAIN's rate limit ramps the applied correction to zero; an integer
register cannot carry one (the service writes 0 for it, docs/register_map.md), so a map of scaled registers
refuses only through its float32 ones (docs/plc.md, "The outputs").
"""

from __future__ import annotations

import itertools
import math
import struct
from pathlib import Path

import pytest
import test_plc_library_run as run
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cell.plc import Endpoint, generate
from plc_link.contract import to_plc
from plc_link.register_map import INT_RANGE, TYPES, RegisterMap

cells = run.cells
NAN_BITS = (0x7FC00000, 0xFFC00000, 0x7F800001, 0x7F800000, 0xFF800000)   # NaN, x86's default NaN, a signalling
BAD = [struct.unpack("<f", struct.pack("<I", b))[0] for b in NAN_BITS]   # NaN's bits as a REAL, +inf, -inf
STEP = 2.0 * 0.001                         # MAIN: fMaxRateDegPerS 2.0 x a 1 ms task


def mixed_map(tmp_path: Path) -> Path:
    """`run.scaled_map` with corrections 4..6 back in float32 registers: 1..3 in INT at 0.01 deg (which cannot
    carry a NaN), 4..6 REAL (which can); the joints in DINT at 0.001 deg."""
    data = yaml.safe_load(run.scaled_map(tmp_path).read_text())
    for r in data["to_plc"]["registers"]:
        if r["name"] in ("correction_q4", "correction_q5", "correction_q6"):
            r["type"] = "float32"
            r.pop("scale")
    path = tmp_path / "mixed.yaml"
    path.write_text(yaml.safe_dump(data))
    return path


@pytest.fixture(scope="module")
def libraries(tmp_path_factory) -> dict[str, tuple[RegisterMap, list[Path]]]:
    """The committed library (MAIN calls FB_StiffComp over ADS), the shipped map's with MAIN on the Modbus
    block, and the mixed map's (Modbus)."""
    out = {"shipped": (RegisterMap.from_yaml(run.SHIPPED_MAP), sorted(run.COMMITTED.iterdir()))}
    for name, rmap in (("shipped_modbus", out["shipped"][0]),
                       ("mixed", RegisterMap.from_yaml(mixed_map(tmp_path_factory.mktemp("map"))))):
        folder = tmp_path_factory.mktemp(name)
        for rel, data in generate(rmap, Endpoint(), ("twincat",), "modbus").items():
            (folder / Path(rel).name).write_bytes(data)
        out[name] = (rmap, sorted(folder.iterdir()))
    return out


# (library, block, the correction register that carries the bad value)
CASES = [("shipped", "FB_StiffComp", 3), ("shipped_modbus", "FB_StiffCompModbus", 3), ("mixed", "FB_StiffCompModbus", 5)]


def poisoned(joint: int, value: float) -> tuple[float, ...]:
    return tuple(value if i == joint else c for i, c in enumerate(run.CORRECTION, 1))


@pytest.mark.parametrize("bad", BAD, ids=[f"{b:08X}" for b in NAN_BITS])
@pytest.mark.parametrize(("which", "block", "joint"), CASES)
def test_a_correction_that_is_not_finite_is_refused(libraries, cells, which, block, joint, bad):
    cell = run.Cell(libraries, which, block, run.fixed(5))
    cells.append(cell)
    cell.run(200)
    assert cell.fb.bValid and not cell.fb.bCorrectionInvalid
    cell.service.correction = poisoned(joint, bad)
    cell.run(30)
    raw = getattr(cell.fb.stToPlc, f"correction_q{joint}")      # the register as the map carries it
    assert struct.pack("<f", raw) == struct.pack("<f", bad) or (math.isnan(raw) and math.isnan(bad))
    assert cell.fb.bAlive and cell.fb.bCorrectionInvalid and not cell.fb.bValid and not cell.fb.bError
    assert cell.fb.aCorrectionDeg == [0.0] * 6
    cell.service.correction = run.CORRECTION
    cell.run(30)
    assert cell.fb.bValid and not cell.fb.bCorrectionInvalid
    assert cell.fb.aCorrectionDeg[2] == pytest.approx(0.5)


def test_an_integer_register_cannot_carry_a_nan_so_the_block_stays_valid(libraries, cells):
    """The service writes 0 for a NaN in an integer register (its encoding): the block sees a finite 0."""
    cell = run.Cell(libraries, "mixed", "FB_StiffCompModbus", run.fixed(5))
    cells.append(cell)
    cell.service.correction = poisoned(1, math.nan)
    cell.run(200)
    assert cell.fb.stToPlc.correction_q1 == 0 and cell.fb.bValid and not cell.fb.bCorrectionInvalid
    assert cell.fb.aCorrectionDeg[0] == 0.0 and cell.fb.aCorrectionDeg[2] == pytest.approx(0.5)


@pytest.mark.parametrize(("which", "block", "joint"), CASES)
def test_main_ramps_the_applied_correction_to_zero_and_its_command_stays_finite(libraries, cells, which, block,
                                                                                joint):
    cell = run.Cell(libraries, which, block, run.fixed(5), task="MAIN")
    cells.append(cell)
    main = cell.program
    main.aReferenceDeg[:] = [10.0] * 6
    cell.run(1100)                                  # 2.0 deg at 2 deg/s: every joint has reached its correction
    assert main.aAppliedDeg[2] == pytest.approx(0.5, abs=1e-6)
    cell.service.correction = poisoned(joint, math.nan)
    applied = []
    cell.run(1100, lambda now: applied.append((list(main.aAppliedDeg), list(main.aCommandDeg))))
    assert all(math.isfinite(x) for a, c in applied for x in a + c)
    for (a0, _), (a1, _) in itertools.pairwise(applied):                  # towards zero, a step at most
        assert all(abs(y) <= abs(x) and abs(x - y) <= STEP * (1 + 1e-5) for x, y in zip(a0, a1, strict=True))
    assert main.aAppliedDeg == [0.0] * 6 and main.aCommandDeg == [10.0] * 6
    assert not main.fbStiffComp.bValid and main.fbStiffComp.bCorrectionInvalid


def register_values(rmap: RegisterMap):
    """Any content of the to_plc registers: an integer register any value of its type, a float32 one any REAL
    (NaN and the infinities included)."""
    fields = {}
    for r in rmap.by_name.values():
        if r.direction != "to_plc":
            continue
        if r.type == "float32":
            fields[r.name] = st.floats(width=32)
        else:
            lo, hi = INT_RANGE[TYPES[r.type][0]]
            fields[r.name] = st.integers(lo, hi).map(lambda raw, s=r.scale: raw / s)
    return st.fixed_dictionaries(fields)


REALS = st.floats(width=32)


@pytest.mark.parametrize(("which", "block"), [("shipped", "FB_StiffComp"), ("mixed", "FB_StiffCompModbus")])
@given(data=st.data())
@settings(max_examples=15, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])
def test_no_register_content_or_joint_makes_main_raise_or_command_a_non_finite_value(libraries, which, block, data):
    """MAIN and its block, on registers holding anything (a healthy service's heartbeat or not), joints
    anything: no exception, and every REAL the program commands finite (aCorrectionDeg, aAppliedDeg,
    aCommandDeg); a non-finite correction register refuses the correction."""
    rmap = libraries[which][0]
    cell = run.Cell(libraries, which, block, run.fixed(2), task="MAIN")
    try:
        records = data.draw(st.lists(st.tuples(register_values(rmap), st.booleans()), min_size=1, max_size=3))
        cell.fb.aJointsDeg[:] = data.draw(st.lists(REALS, min_size=6, max_size=6))
        for values, healthy in records:
            def step(values=values, healthy=healthy):
                cell.service.cycles += 1
                live = {"heartbeat": cell.service.cycles & 0xFFFF, "cycle_count": cell.service.cycles,
                        "status_word": int(run.RUNNING), "fault_word": 0} if healthy else {}
                cell.service.image.publish(to_plc(**{**values, **live}))
            cell.service.step = step
            cell.run(25)
            fb, main = cell.fb, cell.program
            commanded = [*fb.aCorrectionDeg, *main.aAppliedDeg, *main.aCommandDeg]
            assert all(math.isfinite(x) for x in commanded), commanded
            service = [getattr(fb.stToPlc, f"correction_q{i}") for i in range(1, 7)]
            # the block's rule (docs/plc.md): within +-3.4E38, so NaN, the infinities and the few REALs beyond
            assert fb.bCorrectionInvalid == (not all(-3.4e38 <= x <= 3.4e38 for x in service)), service
            if not fb.bValid:
                assert fb.aCorrectionDeg == [0.0] * 6
            assert fb.bValid == (healthy and not fb.bCorrectionInvalid), (healthy, fb.bAlive, fb.nStatusWord)
    finally:
        cell.close()
