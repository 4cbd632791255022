"""Commissioning: the modes identified from a force and a path (stiffness/dynamics/modes.py).

Recovery: a record made by the structure's own response (known modes, directions, lag and compliance) under
a random force, with 1 um of noise, gives back the frequencies (0.5 %), dampings (10 %), directions and the
lag (0.5 ms); a force that does not change, or a record too short, is refused.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from stiffness.dynamics.modes import Record, _late, identify, read_record
from stiffness.dynamics.structure import Structure
from stiffness.errors import DataError


def synthetic(seed=2, lag_ms=6.0, modes=None):
    rng = np.random.default_rng(seed)
    R = Rotation.from_rotvec([0.3, -0.2, 0.5]).as_matrix()
    modes = modes or [{"hz": 9.0, "damping": 0.03, "direction": list(R[:, 0])},
                      {"hz": 15.0, "damping": 0.04, "direction": list(R[:, 1])}]
    st = Structure(Structure.Config(modes=modes, lag_ms=lag_ms))
    t = np.arange(0.0, 4.0, 0.001)
    steps = np.repeat(rng.normal(0.0, 200.0, (len(t) // 50 + 1, 3)), 50, axis=0)[:len(t)]
    F = steps + rng.normal(0.0, 50.0, (len(t), 3))                 # steps and a broadband part
    C = np.diag([1.0e-6, 1.5e-6, 0.8e-6]) + 2e-7
    rec = Record(t, F, np.zeros((len(t), 3)))
    d = st.respond(_late(rec, lag_ms / 1000.0) @ C.T, 0.001) + rng.normal(0.0, 1e-6, (len(t), 3))
    return Record(t, F, d), st


def test_known_modes_come_back():
    rec, truth = synthetic()
    found = identify(rec, 2)
    assert found.structure.cfg.lag_ms == pytest.approx(truth.cfg.lag_ms, abs=0.5)
    for got, want in zip(found.structure.cfg.modes, truth.cfg.modes):
        assert got.hz == pytest.approx(want.hz, rel=0.005)
        assert got.damping == pytest.approx(want.damping, rel=0.1)
        assert abs(np.dot(got.direction, want.direction)) > 0.999
    assert found.explained > 0.99 > found.explained_static


def test_the_record_file_round_trip_and_bad_records(tmp_path):
    rec, _ = synthetic()
    path = tmp_path / "rec.csv"
    rows = np.column_stack([rec.t, rec.force, rec.deflection * 1000.0])
    np.savetxt(path, rows, delimiter=",", header="t_s,fx_N,fy_N,fz_N,dx_mm,dy_mm,dz_mm", comments="")
    back = read_record(path)
    np.testing.assert_allclose(back.deflection, rec.deflection, atol=1e-12)
    with pytest.raises(DataError, match="at least 200"):
        identify(Record(rec.t[:100], rec.force[:100], rec.deflection[:100], "short"), 2)
    flat = Record(rec.t, np.ones_like(rec.force), rec.deflection, "flat")
    with pytest.raises(DataError, match="the force does not change"):
        identify(flat, 2)
