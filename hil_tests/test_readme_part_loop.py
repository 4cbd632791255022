"""The README's part loop ("Cut, measure, learn, cut again") as written: its bash block, read from README.md (so
this test breaks when the README drifts), run by bash in a folder of its own that holds what a checkout holds
beside it (examples/, config/, .venv/bin/stiffcomp). Every command must succeed, every file it names must be
made, and the model learned from the first part must cut the second far better. The model it starts from is
shipped (examples/too_stiff_reference.yaml), and is the one the benchmark and the HIL tests start from."""

from __future__ import annotations

import os
import re
import subprocess
import sys

import numpy as np

from hil.testing import ROTATIONAL, scaled_model_file
from stiffness.model.stiffness_model import StiffnessModel
from testlib.hil import ROOT

TRUTH = ROOT / "examples" / "truth_reference.yaml"
HEADING = "### Cut, measure, learn, cut again"
PART_ERROR = re.compile(r"part error \(virtual CMM, mean \|normal deviation\|\): ([0-9.]+) mm")


def readme_block() -> str:
    """The first bash block under the part loop's heading in README.md."""
    text = (ROOT / "README.md").read_text()
    found = re.search(r"```bash\n(.*?)```", text[text.index(HEADING):], re.DOTALL)
    assert found, f"README.md: no bash block under {HEADING!r}"
    return found.group(1)


def test_the_shipped_start_is_the_model_the_benchmark_starts_from(tmp_path):
    shipped = StiffnessModel.from_yaml(ROOT / "examples" / "too_stiff_reference.yaml")
    made = StiffnessModel.from_yaml(scaled_model_file(TRUTH, 0.6, tmp_path / "start.yaml", keys=ROTATIONAL))
    assert shipped.param_labels() == made.param_labels()
    np.testing.assert_allclose(shipped.theta, made.theta, rtol=1e-9)


def test_the_readme_part_loop_runs_as_written(tmp_path):
    block = readme_block()
    assert "$S part learn" in block and "$S hil circle" in block
    for name in ("examples", "config"):
        (tmp_path / name).symlink_to(ROOT / name)
    wrapper = tmp_path / ".venv" / "bin" / "stiffcomp"
    wrapper.parent.mkdir(parents=True)
    wrapper.write_text(f'#!/bin/sh\nexec "{sys.executable}" -m tools.cli "$@"\n')
    wrapper.chmod(0o755)
    for path in re.findall(r"\bexamples/\S+\.yaml", block):        # what it reads is shipped
        assert (ROOT / path).is_file(), path
    env = dict(os.environ, PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1")
    r = subprocess.run(["bash", "-e", "-c", block], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=1200, check=False)
    assert r.returncode == 0, f"{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    for made in ("out/cut1.csv", "out/part1.csv", "out/part1/index.html", "out/learned.yaml"):
        assert (tmp_path / made).is_file(), made
    first, again = (float(v) for v in PART_ERROR.findall(r.stdout))
    assert again < 0.2 * first, (first, again)        # the learned model cuts the part far better
    assert "learned from 1 part(s)" in r.stdout and "verdict: " in r.stdout
