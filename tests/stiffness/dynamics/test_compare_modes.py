"""The model's modes against a record's (`stiffness.dynamics.compare`): a record made by a known structure (10 Hz
along x, 23 Hz along y, 3 %; hammer taps along x and y, 4 s at 500 Hz; 1 um of noise) names

* nothing against the structure itself;
* the 23 Hz mode missing against a model without it, its frequency within 2 %;
* a mode 20 % off in frequency, and one with half its damping, each by how much;

and the model's modes leave more of the record than the record's own, except when they are the record's."""

from __future__ import annotations

import numpy as np
import pytest

from stiffness.dynamics.compare import compare
from stiffness.dynamics.modes import Record
from stiffness.dynamics.structure import Structure

DT = 0.002
X10 = {"hz": 10.0, "damping": 0.03, "direction": [1.0, 0.0, 0.0]}
Y23 = {"hz": 23.0, "damping": 0.03, "direction": [0.0, 1.0, 0.0]}


pytestmark = pytest.mark.slow


def structure(*modes, lag_ms: float = 0.0) -> Structure:
    return Structure(Structure.Config(modes=list(modes), lag_ms=lag_ms))


@pytest.fixture(scope="module")
def record() -> Record:
    t = np.arange(0.0, 4.0, DT)
    force = np.zeros((len(t), 3))
    for k, start in enumerate(np.arange(0.3, 3.5, 0.6)):         # 4 ms half-sine taps, x and y in turn
        on = (t >= start) & (t < start + 0.004)
        force[on, k % 2] = 100.0 * np.sin(np.pi * (t[on] - start) / 0.004)
    C = np.diag([2e-6, 1.5e-6, 1e-6])                             # m/N
    d = structure(X10, Y23).respond(force @ C.T, DT)
    d += np.random.default_rng(5).normal(0.0, 1e-6, d.shape)
    return Record(t, force, d, "a synthetic tap test")


def test_the_structure_itself_names_nothing(record):
    v = compare(record, structure(X10, Y23))
    assert v.findings == [] and v.rms_model_mm <= 1.05 * v.rms_found_mm


def test_a_mode_the_model_lacks_is_named_missing_with_its_frequency(record):
    v = compare(record, structure(X10))
    missing = [f for f in v.findings if f.kind == "missing"]
    assert len(missing) == 1 and v.findings[0] is missing[0]
    hz = [m.hz for m in v.found.structure.cfg.modes if abs(m.direction[1]) > 0.7]
    assert len(hz) == 1 and abs(hz[0] - 23.0) <= 0.02 * 23.0
    assert v.rms_model_mm > 2 * v.rms_found_mm


def test_a_mode_off_in_frequency_or_damping_is_named_by_how_much(record):
    off = dict(X10, hz=12.0)
    low = dict(Y23, damping=0.015)
    v = compare(record, structure(off, low))
    kinds = {f.kind: f.text for f in v.findings}
    assert set(kinds) == {"frequency", "damping"}, kinds
    assert "12.00 Hz" in kinds["frequency"] and "(-17 %)" in kinds["frequency"]
    assert "1.5 %" in kinds["damping"]
    assert v.rms_model_mm > v.rms_found_mm
