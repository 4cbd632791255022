"""Loading is bounded by the file: a YAML alias bomb is refused fast and small, a value is quoted short in
any message, a file of garbage keeps 1,000 problems and counts the rest, and an Excel BOM CSV loads."""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import tracemalloc

import pytest
import yaml
from hypothesis import given
from hypothesis import strategies as st

from stiffness.data.measurements import read_measurements
from stiffness.errors import ConfigError, DataError, Problems, quote
from stiffness.files.yaml_schema import read_yaml
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import DATA, MODELS, ROOT

pytestmark = pytest.mark.slow

REF = DATA / "reference_campaign.csv"


def bomb_anchors(levels: int = 9) -> str:
    """Nested anchors: the last one expands to 9**levels leaves (a 'billion laughs')."""
    lines = ['  - &a ["lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol", "lol"]']
    names = "abcdefghijklmnop"
    for k in range(1, levels):
        prev = names[k - 1]
        lines.append(f"  - &{names[k]} [{', '.join(['*' + prev] * 9)}]")
    return "\n".join(lines)


def model_bomb(tmp_path):
    model = yaml.safe_load((MODELS / "kr125_axial.yaml").read_text())
    path = tmp_path / "bomb_model.yaml"
    robot = (MODELS / model["robot"]).resolve()
    path.write_text(f"name: bomb\nrobot: {robot}\ndescription:\n{bomb_anchors()}\n"
                    "noise:\n  position_mm: *i\neffects:\n  - {effect: joint_spring, joint: 1}\n")
    return path


def config_bomb(tmp_path):
    path = tmp_path / "bomb_service.yaml"
    path.write_text(f"x_anchors:\n{bomb_anchors()}\nplc:\n  initial_q_deg: *i\n")
    return path


# What the load itself takes: Python's allocations during it (tracemalloc's peak) and the growth of the
# resident set. Not ru_maxrss: on Linux a child keeps the peak its parent had at the fork across the exec,
# so that figure would be the pytest process's, which grows with the suite.
CHILD = textwrap.dedent("""
    import json, sys, time, tracemalloc
    kind, path = sys.argv[1], sys.argv[2]
    if kind == "model":
        from stiffness.model.stiffness_model import StiffnessModel as M
        load = M.from_yaml
    else:
        from service.config import load_config as load
    def rss_mb():
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * 4096 / 2**20
    before = rss_mb()
    tracemalloc.start()
    t0 = time.perf_counter()
    try:
        load(path)
        msg = None
    except Exception as e:
        msg = f"{type(e).__name__}: {e}"
    dt = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1] / 2**20
    print(json.dumps({"s": dt, "rss_mb": max(rss_mb() - before, peak), "error": msg}))
""")


@pytest.mark.parametrize("kind, make", [("model", model_bomb), ("config", config_bomb)])
def test_an_alias_bomb_is_refused_within_10_s_under_500_mb(tmp_path, kind, make):
    path = make(tmp_path)
    # a hard ceiling on the child's address space: a bomb that expanded would die here, not take the machine
    limit = "import resource; resource.setrlimit(resource.RLIMIT_AS, (4 << 30, 4 << 30))\n"
    out = subprocess.run([sys.executable, "-c", limit + CHILD, kind, str(path)], check=False,
                         capture_output=True,
                         text=True, timeout=300, cwd=ROOT)
    assert out.returncode == 0, out.stderr[-2000:]
    r = json.loads(out.stdout.strip().splitlines()[-1])
    assert r["error"] is not None and "alias" in r["error"] and str(path) in r["error"], r
    assert r["s"] < 10.0 and r["rss_mb"] < 500.0, r
    assert len(r["error"]) < 400, r


def test_an_alias_names_the_file_and_line(tmp_path):
    path = tmp_path / "m.yaml"
    path.write_text("a: &x 1\nb: *x\n")
    with pytest.raises(ConfigError, match=r"m\.yaml: line 2 .*alias \(\*x\)"):
        read_yaml(path)
    path.write_text("a: &x 1\nb: 2\n")               # an anchor alone is harmless
    assert read_yaml(path) == {"a": 1, "b": 2}


@given(st.recursive(st.none() | st.booleans() | st.floats() | st.text(max_size=500),
                    lambda inner: st.lists(inner, max_size=30) | st.dictionaries(st.text(max_size=50), inner,
                                                                                 max_size=30),
                    max_leaves=400))
def test_a_quoted_value_is_at_most_80_characters(value):
    q = quote(value)
    assert len(q) <= 80
    if not isinstance(value, (list, dict)) and len(repr(value)) <= 60:
        assert q == repr(value)            # a short scalar is quoted in full


def test_a_long_value_is_quoted_short_in_a_model_and_a_validated_file(tmp_path):
    model = yaml.safe_load((MODELS / "kr125_axial.yaml").read_text())
    model["robot"] = str((MODELS / model["robot"]).resolve())
    model["noise"] = {"position_mm": "9" * 100_000}
    path = tmp_path / "long.yaml"
    path.write_text(yaml.safe_dump(model))
    with pytest.raises(ConfigError) as e:
        StiffnessModel.from_yaml(path)
    assert "noise.position_mm" in str(e.value) and len(str(e.value)) < len(str(path)) + 200
    from service.config import ServiceConfigError, load_config
    cfg = tmp_path / "svc.yaml"
    cfg.write_text(yaml.safe_dump({"plc": {"initial_q_deg": ["x" * 100_000] * 6}}))
    with pytest.raises(ServiceConfigError) as e:
        load_config(cfg)
    assert all(len(line) < len(str(cfg)) + 250 for line in str(e.value).splitlines()), str(e.value)[:500]


def garbage_csv(path, n_lines: int) -> None:
    header = REF.read_text().splitlines()[0]
    ncol = len(header.split(","))
    row = ",".join(["garbage!"] * ncol)
    path.write_text(header + "\n" + "\n".join([row] * n_lines) + "\n")


def test_problems_stop_collecting_at_1000_and_count_the_rest(tmp_path):
    path = tmp_path / "garbage.csv"
    garbage_csv(path, 3000)
    with pytest.raises(DataError) as e:
        read_measurements(path)
    assert len(e.value.problems) == Problems.LIMIT
    assert e.value.count > 3000 * 14                       # every numeric cell and the body, counted
    assert f"{e.value.count} problem(s) in 3000 rows" in str(e.value)
    assert f"... and {e.value.count - 20} more" in str(e.value)


def test_parquet_problems_are_capped_the_same_way(tmp_path):
    pa = pytest.importorskip("pyarrow")
    import pyarrow.parquet as pq
    header = REF.read_text().splitlines()[0].split(",")
    pq.write_table(pa.table({h: ["garbage!"] * 2000 for h in header}), tmp_path / "garbage.parquet")
    with pytest.raises(DataError) as e:
        read_measurements(tmp_path / "garbage.parquet")
    assert len(e.value.problems) == Problems.LIMIT and e.value.count > 2000 * 14
    assert "line 2:" in e.value.problems[0]


def test_memory_is_bounded_by_the_file_not_by_its_problems(tmp_path):
    path = tmp_path / "garbage.csv"
    garbage_csv(path, 20_000)
    size = path.stat().st_size
    tracemalloc.start()
    try:
        with pytest.raises(DataError):
            read_measurements(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 4 * size, (peak, size)


def test_a_csv_with_a_utf8_bom_loads(tmp_path, robot):
    path = tmp_path / "excel.csv"
    path.write_bytes(b"\xef\xbb\xbf" + REF.read_bytes())
    d = read_measurements(path, robot)
    ref = read_measurements(REF, robot)
    assert len(d) == len(ref) and (d.deflection[d.measured] == ref.deflection[ref.measured]).all()


def test_what_stiffcomp_writes_it_reads_again_even_with_shared_values(tmp_path):
    """Aliases are refused on reading, so stiffcomp never writes one: a value shared twice is written twice."""
    from stiffness.files.yaml_schema import dump_yaml
    q = [0.0, -90.0, 90.0, 0.0, 45.0, 0.0]
    data = {"a": {"q_deg": q}, "b": {"q_deg": q}}
    assert "*id001" in yaml.safe_dump(data)                # PyYAML itself would write an alias
    path = tmp_path / "shared.yaml"
    path.write_text(dump_yaml(data))
    assert read_yaml(path) == data
