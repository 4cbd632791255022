"""The measurement reader: every bad row is reported with its line; good files load in any column order."""

import csv

import numpy as np
import pytest

from stiffness.data.measurements import COLUMNS, read_measurements
from stiffness.errors import DataError
from testlib.common import DATA

REF = DATA / "reference_campaign.csv"


def write_rows(path, header, rows):
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow(header)
        w.writerows(rows)


def reference_rows(n=20):
    with open(REF) as fh:
        r = list(csv.reader(fh))
    return r[0], r[1:n + 1]


def test_reference_loads(robot):
    d = read_measurements(REF, robot)
    assert len(d) == 5355 and d.configs == ["R1", "R2", "R3", "R4", "R5"]
    assert set(np.unique(d.body)) == set(range(7))
    first, inv = d.readings()
    assert len(first) == 5355 // 7 and (np.bincount(inv) == 7).all()


def test_any_column_order_and_extra_columns(tmp_path, robot):
    header, rows = reference_rows()
    perm = list(reversed(range(len(header))))
    write_rows(tmp_path / "p.csv", [header[i] for i in perm] + ["note"],
               [[r[i] for i in perm] + ["x"] for r in rows])
    a = read_measurements(tmp_path / "p.csv", robot)
    b = read_measurements(REF, robot).subset(np.arange(20))
    np.testing.assert_array_equal(a.deflection, b.deflection)
    np.testing.assert_array_equal(a.wrench, b.wrench)
    assert a.ignored_columns == ["note"]


def test_every_bad_row_is_reported_with_its_line(tmp_path, robot):
    header, rows = reference_rows()
    i = {c: header.index(c) for c in COLUMNS}
    rows[2][i["fx_N"]] = "abc"           # line 4
    rows[5][i["dz_mm"]] = "nan"          # line 7
    rows[7][i["body"]] = "A7"            # line 9
    rows[9][i["q2_deg"]] = "80"          # line 11: A2 limit is 35 deg
    rows[11] = rows[11][:-1]             # line 13: a field short
    write_rows(tmp_path / "bad.csv", header, rows)
    with pytest.raises(DataError) as e:
        read_measurements(tmp_path / "bad.csv", robot)
    msg = str(e.value)
    for frag in ["line 4: fx_N = 'abc' is not a number", "line 7: dz_mm = 'nan' is not finite",
                 "line 9: body = 'A7'", "line 11: q2_deg = 80 is outside the joint limits",
                 "line 13: 20 fields, the header has 21", "nothing was loaded"]:
        assert frag in msg
    assert len(e.value.problems) == 5


def test_missing_column_and_empty_file(tmp_path):
    header, rows = reference_rows()
    # a deflection column may be absent (issue 12: partial measurements); a required one may not
    k = header.index("mz_Nm")
    write_rows(tmp_path / "m.csv", header[:k] + header[k + 1:], [r[:k] + r[k + 1:] for r in rows])
    with pytest.raises(DataError, match="line 1: missing column.*mz_Nm"):
        read_measurements(tmp_path / "m.csv")
    (tmp_path / "e.csv").write_text("")
    with pytest.raises(DataError, match="empty"):
        read_measurements(tmp_path / "e.csv")
    with pytest.raises(DataError, match="not found"):
        read_measurements(tmp_path / "none.csv")


def test_parquet_round_trip(tmp_path, robot):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq
    d = read_measurements(REF, robot).subset(np.arange(70))
    d.to_csv(tmp_path / "a.csv")
    with open(tmp_path / "a.csv") as fh:
        header, *rows = list(csv.reader(fh))
    cols = {h: [r[k] for r in rows] for k, h in enumerate(header)}
    table = pa.table({h: (v if h in ("config", "body") else [float(x) for x in v]) for h, v in cols.items()})
    pq.write_table(table, tmp_path / "a.parquet")
    p = read_measurements(tmp_path / "a.parquet", robot)
    np.testing.assert_allclose(p.deflection, d.deflection, atol=1e-6)
    np.testing.assert_array_equal(p.config, d.config)
    np.testing.assert_array_equal(p.body, d.body)


def test_csv_write_read_round_trip(tmp_path, robot):
    d = read_measurements(REF, robot)
    d.to_csv(tmp_path / "rt.csv")
    e = read_measurements(tmp_path / "rt.csv", robot)
    np.testing.assert_allclose(e.deflection, d.deflection, atol=1e-7)
    np.testing.assert_allclose(e.wrench, d.wrench, atol=1e-4)


def test_empty_cells_are_not_measured_and_round_trip(tmp_path):
    """Issue 12: an empty cell is a component not measured in that row; NaN stays an error."""
    header, rows = reference_rows()
    i = {c: k for k, c in enumerate(header)}
    rows[0][i["rx_deg"]] = ""                    # line 2: rotation x not measured
    for r in rows[1:4]:                          # lines 3-5: position only
        for c in ("rx_deg", "ry_deg", "rz_deg"):
            r[i[c]] = ""
    write_rows(tmp_path / "p.csv", header, rows)
    d = read_measurements(tmp_path / "p.csv")
    assert d.measured.sum() == 6 * len(rows) - 1 - 9
    assert not d.measured[0, 3] and d.measured[0, [0, 1, 2, 4, 5]].all()
    assert np.isnan(d.deflection[1:4, 3:]).all()
    d.to_csv(tmp_path / "back.csv")
    back = read_measurements(tmp_path / "back.csv")
    np.testing.assert_array_equal(back.measured, d.measured)
    np.testing.assert_allclose(back.deflection[d.measured], d.deflection[d.measured], atol=1e-6)


def test_a_row_must_measure_something_and_a_file_must_have_a_deflection_column(tmp_path):
    header, rows = reference_rows()
    i = {c: k for k, c in enumerate(header)}
    for c in ("dx_mm", "dy_mm", "dz_mm", "rx_deg", "ry_deg", "rz_deg"):
        rows[2][i[c]] = ""                       # line 4
    write_rows(tmp_path / "m.csv", header, rows)
    with pytest.raises(DataError) as e:
        read_measurements(tmp_path / "m.csv")
    assert any("line 4: no deflection component" in p for p in e.value.problems)
    keep = [k for k, c in enumerate(header) if not c.endswith(("_mm", "_deg")) or c.startswith("q")]
    write_rows(tmp_path / "n.csv", [header[k] for k in keep], [[r[k] for k in keep] for r in rows])
    with pytest.raises(DataError, match="line 1: no deflection column"):
        read_measurements(tmp_path / "n.csv")
