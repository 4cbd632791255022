"""The HIL's true payload is its own (hil/payload.py, the scenario's ``payload`` section), not the
service's gravity compensation nor its config, so the HIL catches a gravity error of the service.

Properties: the HIL's physics (each body's weight summed) and the service's (one combined mass and
centre of gravity) agree on the same payload in any orientation, as two independent derivations of
one law must; a service config whose payload is wrong leaves exactly the weight it misses in the
external wrench, in the devices and in the closed loop, where the PLC reads it and the path error grows.
"""

from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from hil.lockstep import run_lockstep
from hil.payload import TruePayload
from hil.report import evaluate_pass
from hil.world import World
from service.gravity import PAYLOAD_BODIES, GravityCompensator, GravityConfig
from stiffness.model.stiffness_model import StiffnessModel
from testlib.hil import EXAMPLES, OUT, ROOT, scenario

TRUTH = EXAMPLES / "truth_reference.yaml"
FEED = 60.0                      # mm/s: a 3.7 s circle


def section(masses, cogs, bias=(0.0,) * 6, g=(0.0, 0.0, -9.81)) -> GravityConfig:
    bodies = {b: {"mass_kg": m, "cog_mm": list(c)} for b, m, c in zip(PAYLOAD_BODIES, masses, cogs)}
    return GravityConfig(g_mps2=list(g), bias=list(bias), **bodies)


mass = st.floats(0.0, 50.0)
cog = st.lists(st.floats(-300.0, 300.0), min_size=3, max_size=3)


@settings(max_examples=80, deadline=None)
@given(st.lists(mass, min_size=4, max_size=4), st.lists(cog, min_size=4, max_size=4),
       st.integers(0, 2**31 - 1))
def test_the_hil_and_the_service_agree_on_a_payload_they_both_know(masses, cogs, seed):
    sec = section(masses, cogs)
    R = Rotation.random(random_state=seed).as_matrix()
    np.testing.assert_allclose(TruePayload(sec).wrench(R), GravityCompensator.from_config(sec).payload_wrench(R),
                               rtol=1e-9, atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(st.floats(0.5, 30.0), st.integers(0, 2**31 - 1))
def test_a_wrong_mass_in_the_service_leaves_the_missing_weight(missing_kg, seed):
    """The service compensating with too light a tool reports the weight it misses as an external force."""
    truth = section([0.0, 12.0, 0.0, 0.0], [[0, 0, 0], [0, 0, 110], [0, 0, 0], [0, 0, 0]], [3, -2, 5, 0.1, -0.05, 0.02])
    wrong = truth.model_copy(deep=True)
    wrong.tool.mass_kg = 12.0 - missing_kg
    R = Rotation.random(random_state=seed).as_matrix()
    true = TruePayload(truth)
    reading = true.wrench(R) + true.bias
    external = np.array(GravityCompensator.from_config(wrong).compensate(reading, R))
    np.testing.assert_allclose(external[:3], missing_kg * R.T @ np.array(truth.g_mps2), atol=1e-9)
    assert np.allclose(GravityCompensator.from_config(truth).compensate(reading, R), 0.0, atol=1e-9)


def test_the_sensor_carries_the_scenarios_payload():
    sc = scenario()
    world = World(sc, StiffnessModel.from_yaml(TRUTH).robot, sc.payload)
    before_the_cut = world.sensor_wrench(np.array([world.t_start]))[0]
    weight = np.linalg.norm((before_the_cut - world.gravity.bias)[:3])
    assert weight == pytest.approx(sum(getattr(sc.payload, b).mass_kg for b in PAYLOAD_BODIES) * 9.81, rel=1e-12)


def test_the_hil_does_not_use_the_services_gravity_compensation():
    """No module of hil/ imports or names the service's compensator (its docstrings may mention it)."""
    hits = []
    for p in sorted((ROOT / "hil").glob("*.py")):
        for node in ast.walk(ast.parse(Path(p).read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.ImportFrom | ast.Import)
                     else [node.id] if isinstance(node, ast.Name) else [node.attr] if isinstance(node, ast.Attribute)
                     else [])
            hits += [f"{p.name}:{node.lineno}" for n in names if n == "GravityCompensator"]
    assert hits == []


def test_a_wrong_gravity_config_shows_in_the_closed_loop(tmp_path):
    """The service config says the tool weighs 6 kg; the sensor carries 12. Before the cut the PLC reads
    the missing 6 kg as a force along gravity, where with the right config it reads none, and the
    compensated path error grows: its slow part (averaged over 0.2 s, two periods of the arm's first mode,
    so the ringing that no gravity config changes drops out) is several times the right config's. In lock
    step (`hil.lockstep`: the service's own cycle and the PLC's logic, deterministic)."""
    sc = scenario(FEED)
    truth = StiffnessModel.from_yaml(TRUTH)
    right = run_lockstep(sc, truth, TRUTH, True, tmp_path / "right")
    wrong = run_lockstep(sc, truth, TRUTH, True, tmp_path / "wrong",
                         {"gravity": {"tool": {"mass_kg": 6.0}}})
    ev_right, ev_wrong = (evaluate_pass(sc, truth, r)[1] for r in (right, wrong))
    missing = 6.0 * np.array(sc.payload.g_mps2)                      # base axes, N
    for r, expected in ((right, np.zeros(3)), (wrong, missing)):
        t = r.log.t
        hold = (t < -0.02) & r.log.link          # before the cut: no process force, only the payload
        assert hold.sum() >= 10
        f = r.log.to_plc[hold][:, [OUT.index(f"wrench_f{a}") for a in "xyz"]]
        np.testing.assert_allclose(f.mean(0), expected, atol=2.0)
    assert slow_error(ev_wrong) > 3.0 * slow_error(ev_right), (slow_error(ev_wrong), slow_error(ev_right))


def slow_error(ev: dict, span_s: float = 0.2) -> float:
    """Mean |path error| over the cut after a moving average over ``span_s`` (mm)."""
    t, e = ev.t[ev.cut], ev.err_mm[ev.cut]
    n = max(round(span_s / np.median(np.diff(t))), 1)
    return float(np.abs(np.convolve(e, np.ones(n) / n, "same")[n:-n]).mean())
