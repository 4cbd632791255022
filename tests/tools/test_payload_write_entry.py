"""`stiffcomp payload POSES.csv --config FILE --write-entry N --name TEXT`, run as a user runs it: the
identified payload becomes set N of the file's table, the rest of the file's data stays, a taken index
needs --replace, and the written set loads and, selected by the PLC's index, removes the weight."""

from __future__ import annotations

import csv
import difflib
from types import SimpleNamespace

import numpy as np

from hil.payload import TruePayload
from hil.testing import write_config
from service.ati import Reading
from service.compensation import FastPredictor
from service.config import load_config
from service.gravity import GravityConfig
from service.pipeline import Cycle
from stiffness.files.yaml_schema import read_yaml
from stiffness.model.stiffness_model import StiffnessModel
from testlib.common import ROOT
from tools import payload_cmd
from tools.cli import main

SHIPPED = ROOT / "config" / "default.yaml"
EXAMPLE = ROOT / "examples" / "payload_poses.csv"       # the guide's example: a 14.2 kg spindle

TRUTH = GravityConfig(tool={"mass_kg": 9.5, "cog_mm": [12.0, -4.0, 95.0]}, bias=[1.5, -2.5, 3.0, 0.2, -0.1, 0.05])
POSES = [[0, -90, 90, a4, a5, a6] for a4 in (-60, 0, 70) for a5 in (-50, 30, 80) for a6 in (0, 120)]


def stiffcomp(capsys, *args):
    """The command line in this process (its three runs would each pay the start of an interpreter)."""
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    return SimpleNamespace(returncode=code, stdout=out.out, stderr=out.err)


def poses_csv(path, fp: FastPredictor):
    """Static readings of the TRUTH payload at POSES (the HIL's physics, pinocchio's sensor axes)."""
    truth = TruePayload(TRUTH)
    with open(path, "w", newline="") as fh:
        w = csv.writer(fh)
        w.writerow([f"q{i}_deg" for i in range(1, 7)] + ["fx_N", "fy_N", "fz_N", "mx_Nm", "my_Nm", "mz_Nm"])
        for q in POSES:
            fp.kinematics(np.radians(q))
            w.writerow(q + (truth.wrench(np.array(fp.R_s)) + truth.bias).tolist())
    return path


def test_write_entry_round_trips_into_a_set_the_plc_selects(tmp_path, capsys):
    config = write_config(tmp_path, {"gravity": {"payloads": [{"index": 1, "name": "old spindle", "mass_kg": 3.0,
                                                                "cog_mm": [0, 0, 50]}]}})
    cfg = load_config(config)
    model = StiffnessModel.from_yaml(cfg.resolve(cfg.model.file))
    poses = poses_csv(tmp_path / "poses.csv", FastPredictor(model))
    before = read_yaml(config)

    r = stiffcomp(capsys, "payload", poses, "--config", config, "--write-entry", 3, "--name", "gripper B", "--tcp-mm", 0, 0, 180)
    assert r.returncode == 0, r.stderr
    assert "added gravity.payloads set 3 'gripper B'" in r.stdout and "comments included, is as it was" in r.stdout
    after = read_yaml(config)
    assert {k: v for k, v in after.items() if k != "gravity"} == {k: v for k, v in before.items() if k != "gravity"}
    assert {k: v for k, v in after["gravity"].items() if k != "payloads"} == \
        {k: v for k, v in before["gravity"].items() if k != "payloads"}
    sets = load_config(config).gravity.payload_sets()
    assert sets[1].name == "old spindle" and sets[3].name == "gripper B" and sets[3].tcp_mm == (0.0, 0.0, 180.0)
    assert abs(sets[3].mass_kg - 9.5) < 1e-3
    np.testing.assert_allclose(sets[3].cog_mm, TRUTH.tool.cog_mm, atol=0.01)
    np.testing.assert_allclose(sets[3].bias, TRUTH.bias, atol=1e-3)

    text = config.read_text()
    r = stiffcomp(capsys, "payload", poses, "--config", config, "--write-entry", 3, "--name", "again")
    assert r.returncode != 0 and "gravity.payloads already has index 3 ('gripper B', 9.5 kg); --replace" in r.stderr
    assert config.read_text() == text
    r = stiffcomp(capsys, "payload", poses, "--config", config, "--write-entry", 3, "--name", "gripper C", "--replace")
    assert r.returncode == 0 and "replaced gravity.payloads set 3 'gripper C'" in r.stdout, r.stderr
    cfg = load_config(config)
    assert [e.index for e in cfg.gravity.payloads] == [1, 3] and cfg.gravity.payloads[1].name == "gripper C"

    # the PLC selects set 3: the gripper's weight and bias are gone from the wrench after the ramp
    cyc = Cycle.from_config(cfg, model)
    fp = FastPredictor(model)
    q = [5.0, -70.0, 80.0, 30.0, 45.0, 60.0]
    fp.kinematics(np.radians(q))
    reading = Reading((TruePayload(TRUTH).wrench(np.array(fp.R_s)) + TRUTH.bias).tolist(), 0, 0, False)
    n = int(cfg.gravity.switch_ramp_s / 1e-3) + 5
    for k in range(n):
        cyc.step(k * 1e-3, reading, [], 1, k, q, False, 3)
    assert cyc.signals().payload_active == 3 and cyc.faults.word == 0
    assert np.abs(cyc.wrench_sensor[:3]).max() < 0.05 and np.abs(cyc.wrench_sensor[3:]).max() < 0.005


# -- issue 27, item 3: never into the shipped tree without --config; comments and number formats kept --------

def test_write_entry_without_config_is_refused_and_writes_nothing(tmp_path, capsys, monkeypatch):
    """The default --config is the shipped config/default.yaml (a tracked file). Here it is a copy, so the
    old behaviour (rewriting it) shows as a changed file instead of damaging the checkout."""
    stand_in = write_config(tmp_path, {}, name="default.yaml")
    text = stand_in.read_text()
    monkeypatch.setattr(payload_cmd, "DEFAULT_CONFIG", stand_in)
    r = stiffcomp(capsys, "payload", EXAMPLE, "--write-entry", 4, "--name", "T")
    assert r.returncode == 2 and stand_in.read_text() == text
    assert f"--write-entry needs --config FILE, the site config to write the set into; the shipped {stand_in} " \
           "is not written" in r.stderr
    # without --write-entry the shipped config is only read, as before
    r = stiffcomp(capsys, "payload", EXAMPLE)
    assert r.returncode == 0 and "mass_kg: 14.19" in r.stdout and stand_in.read_text() == text


def test_write_entry_keeps_every_comment_and_number_format_of_the_file(tmp_path, capsys):
    """A copy of the shipped config, as the commissioning guide makes it: after two sets are written, the
    file is the old one with the new sets' lines inserted into the table and nothing else changed (the
    flow ``payloads: []`` opens into a block), ``base_id: 0x020`` stays hex, and it loads with both sets."""
    site = tmp_path / "site"
    site.mkdir()
    config = site / "service.yaml"
    config.write_text(SHIPPED.read_text())
    before = config.read_text().splitlines()
    for index, name in ((3, "spindle + D20 mill"), (5, "probe")):
        r = stiffcomp(capsys, "payload", EXAMPLE, "--config", config, "--write-entry", index, "--name", name)
        assert r.returncode == 0, r.stderr
    after = config.read_text().splitlines()
    ops = [op for op in difflib.SequenceMatcher(a=before, b=after, autojunk=False).get_opcodes() if op[0] != "equal"]
    changed = [(before[i1:i2], after[j1:j2]) for tag, i1, i2, j1, j2 in ops if tag != "insert"]
    comment = "# numbered sets the PLC selects by payload_index; 0 is the bodies above"
    assert changed == [([f"  payloads: []                 {comment}"], [f"  payloads:                    {comment}"])]
    inserted = [line for tag, i1, i2, j1, j2 in ops if tag == "insert" for line in after[j1:j2]]
    assert sum(line.startswith("  - index: ") for line in inserted) == 2 and "#" not in "".join(inserted)
    assert "    base_id: 0x020             # base CAN id [0, 0x7F0]; answers on base+5 and base+6" in after
    comments = [line[line.index("#"):] for line in before if "#" in line]
    assert comments == [line[line.index("#"):] for line in after if "#" in line]
    cfg = load_config(config)
    assert cfg.source.ati.base_id == 0x20
    sets = cfg.gravity.payload_sets()
    assert sets[3].name == "spindle + D20 mill" and sets[5].name == "probe" and abs(sets[3].mass_kg - 14.2) < 0.05
    assert after[after.index("  - index: 5") + 5:after.index("  - index: 5") + 7] == ["", "limits:"]
