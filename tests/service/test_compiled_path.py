"""The compiled cycle (`service.kernel`) agrees with the Python path, its reference, to rounding.

Over the agreement cases of every library effect (`test_fast_effects.EXAMPLES`), on the KR 125 without
masses, with its masses (the axial effects at the total torque) and with an identified static torque:
the deflection, the static torque and every history state, cycle by cycle (rtol 1e-9), and δq to the
rounding of its solve (`solve_rtol`), after Newton's refinement to 100 times that. Then the whole signal path of a running `Cycle` (filter, spikes, gravity, tare, a fault
reset, a payload switch, limits) against the Python one; a term with no compiled form leaves the
service on the Python path with one log line; the kinds an effect of the dynamics may use (a wrench
and a deflection filter, `WrenchTerm`, `TwistTerm`) run on both paths alike; and a cycle in steady
state allocates nothing that stays.
"""

from __future__ import annotations

import gc
import logging
import sys

import numpy as np
import pytest
from test_fast_effects import EXAMPLES, load_sequences

from hil.testing import CONFIG, model_with
from plc_link.contract import Command
from service.ati import Reading
from service.compensation import FastPredictor
from service.config import load_config
from service.gravity import PayloadEntry
from service.kernel import NotCompilable
from service.pipeline import Cycle
from stiffness.effects.terms import AxialTerm, TwistTerm, WrenchTerm
from stiffness.kinematics.robot import load_robot
from stiffness.model.stiffness_model import StiffnessModel

pytestmark = pytest.mark.slow

RTOL = 1e-9
ROBOTS = ("kr125", "kr125_masses", "preload identified")
CASES = [pytest.param(name, k, id=f"{name}-{k}") for name in sorted(EXAMPLES) for k in range(len(EXAMPLES[name]))]


def on_robot(model: StiffnessModel, robot: str) -> StiffnessModel:
    d = model.to_dict()
    if robot == "kr125":
        return model
    if robot == "kr125_masses":
        return StiffnessModel.from_dict(d, robot, robot=load_robot(CONFIG / "robots" / "kr125_masses.yaml"))
    d["preload"] = [{"joint": 2, "my2_kgm": -40.0, "my3_kgm": 30.0}, {"joint": 3, "mx3_kgm": 12.0}]
    return StiffnessModel.from_dict(d, robot, robot=model.robot)


def close(a, b, rtol: float = RTOL, atol: float = 1e-12) -> bool:
    """|a - b| <= rtol * max |b| + atol (atol as test_fast_effects: a tared load's rounding is ~1e-19)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return bool(np.all(np.abs(a - b) <= rtol * np.abs(b).max() + atol))


def solve_rtol(fp: FastPredictor) -> float:
    """Rounding of the damped pseudo-inverse: J J^T + λ² I is solved by LU on the Python path and by Cholesky
    on the compiled one; each is exact to cond(J J^T + λ² I) times the machine epsilon, so near a singularity
    (λ = 1e-6 here) the two differ by more than 1e-9 while both are right to their rounding."""
    J = np.asarray(fp.J)
    return max(RTOL, 10 * np.linalg.cond(J @ J.T + fp.lam**2 * np.eye(6)) * np.finfo(float).eps)


@pytest.mark.parametrize("robot", ROBOTS)
@pytest.mark.parametrize("name, k", CASES)
def test_the_compiled_predictor_agrees_with_the_python_one(name, k, robot):
    model = on_robot(model_with(EXAMPLES[name][k]), robot)
    steps = 12
    data = load_sequences(model.robot, 6, steps, seed=200 + 7 * k + len(name))
    py, cc = (FastPredictor(model, damping=1e-6) for _ in range(2))
    py_refined, refined = (FastPredictor(model, damping=1e-6, refinement_iterations=3) for _ in range(2))
    cc.compile()
    refined.compile()
    assert cc.kernel is not None and py.kernel is None
    for start in range(0, len(data), steps):
        q = np.radians(data.q_deg[start])
        for p in (py, cc, py_refined, refined):
            p.reset_history()
            p.kinematics(q)
        rtol = solve_rtol(py)
        assert close(cc.tau_s, py.tau_s) and close(cc.J_pinv, py.J_pinv, rtol)
        for n in range(start, start + steps):
            w = data.wrench[n].tolist()
            dX_py = py.deflection(py.wrench_base(w), 0.001)
            dX_cc = cc.deflection(cc.wrench_base(w), 0.001)
            assert close(dX_cc, dX_py), (n, dX_cc, dX_py)
            assert close(cc.correction(q, dX_cc), py.correction(q, dX_py), rtol)
            # Newton's refinement: three solves at nearby joints, each to its rounding, each feeding the next
            dX = refined.deflection(refined.wrench_base(w), 0.001)
            py_refined.deflection(py_refined.wrench_base(w), 0.001)
            assert close(refined.correction(q, dX), py_refined.correction(q, dX), 100 * rtol)
            for a, b in zip(cc.history, py.history):
                assert close(a.state, b.state)          # the hysteresis state, cycle by cycle


def drive(cycle: Cycle, n: int, seed: int = 1, t0: float = 0.0, plan=None):
    """A moving robot under a milling load, with a tare at 1/3, a fault reset at 1/2, payload set 1 from 2/3
    and every third sample missing; yields after each cycle. ``plan(t)``: the PLC's record at t (the
    dynamic compensation's feedforward reads it)."""
    rng = np.random.default_rng(seed)
    enable, tare, reset = int(Command.ENABLE), int(Command.TARE), int(Command.RESET)
    for k in range(1, n + 1):
        ph = 0.01 * k
        w = [300 * np.cos(ph) + 5 * rng.standard_normal(), 300 * np.sin(ph), 150.0, 20 * np.sin(ph),
             20 * np.cos(ph), 1.0]
        q = [10 + 2 * np.sin(ph), -70 + np.cos(ph), 95.0, 15.0, 40 + np.sin(ph), -20.0]
        cmd = enable | (tare if k == n // 3 else 0) | (reset if k == n // 2 else 0)
        reading = Reading(w, 0, k, False) if k % 3 else None
        t = t0 + 0.001 * k
        cycle.step(t, reading, [], cmd, k, q, payload_index=1 if k > 2 * n // 3 else 0,
                   inputs=plan(t) if plan is not None else None)
        yield k


@pytest.fixture(scope="module")
def cfg():
    c = load_config(CONFIG / "default.yaml")
    c.tare.max_force_N = 2500.0                 # the tare happens under load (the history restarts)
    c.gravity.payloads = [PayloadEntry(index=1, name="spindle 2", mass_kg=18.0, cog_mm=[5.0, 0.0, 140.0],
                                       bias=[1.0, 0, 2.0, 0, 0.1, 0])]
    return c


@pytest.mark.parametrize("robot", ROBOTS)
def test_the_compiled_cycle_agrees_with_the_python_one(cfg, robot):
    model = on_robot(model_with(*[e for entries in EXAMPLES.values() for e in entries[:1]]), robot)
    py, cc = Cycle.from_config(cfg, model), Cycle.from_config(cfg, model)
    cc.compensator.compile()
    for _ in zip(drive(py, 1500), drive(cc, 1500)):
        rtol = solve_rtol(py.compensator.predictor)
        for a, b, tol in ((cc.correction, py.correction, rtol), (cc.dq_deg, py.dq_deg, rtol),
                          (cc.deflection, py.deflection, RTOL), (cc.wrench_base, py.wrench_base, RTOL),
                          (cc.wrench_sensor, py.wrench_sensor, RTOL)):
            assert close(a, b, tol), (a, b)
        assert cc.status_word == py.status_word and cc.faults.word == py.faults.word
    assert cc.tares == py.tares == 1 and cc.compensator.payloads.destination.index == 1     # ramping to set 1
    assert any(cc.correction)


def test_an_effect_without_a_compiled_form_runs_on_the_python_path(caplog, monkeypatch):
    """A term given as a Python callable alone: the service starts, on the Python path, with one log line."""
    import service.compensation
    from service.app import Service

    model = model_with(base="kr125_6dof")
    with pytest.raises(NotCompilable, match="Python callable"):
        fp = FastPredictor(model)
        fp.axial.append(AxialTerm(2, lambda tau: 1e-5))
        fp.compile()
    assert fp.kernel is None
    cfg = load_config(CONFIG / "default.yaml")
    cfg.plc.role, cfg.ads.enabled, cfg.monitoring.enabled = "none", False, False
    terms = service.compensation.fast_terms

    def with_a_callable(m, *dynamics):
        t = terms(m, *dynamics)
        t.axial.append(AxialTerm(2, lambda tau: 1e-5))
        return t

    monkeypatch.setattr(service.compensation, "fast_terms", with_a_callable)
    svc = Service(cfg)
    try:
        with caplog.at_level(logging.INFO, "stiffcomp.service"):
            svc.wait_compiled()
    finally:
        svc.stop()
    lines = [r.getMessage() for r in caplog.records if "Python path" in r.getMessage()]
    assert len(lines) == 1 and "Python callable" in lines[0]
    assert svc.cycle.compensator.kernel is None


def lag_law(s, p, x, dt):
    """A first-order lag of each component, time constant p[0] (s): the shape of a dynamics term."""
    a = dt / (p[0] + dt)
    for i in range(6):
        s[i] += a * (x[i] - s[i])
        x[i] = s[i]


def scale_law(s, p, w, dt):
    """The wrench scaled by p[0], and the number of cycles counted in the state."""
    s[0] += 1.0
    for i in range(6):
        w[i] *= p[0]


def test_wrench_and_twist_terms_run_alike_on_both_paths():
    """The kinds a dynamics effect builds on (issue 26: a predictor of the wrench, a structure's modes)."""
    model = model_with(EXAMPLES["hysteresis"][0])
    py, cc = FastPredictor(model), FastPredictor(model)
    for p in (py, cc):
        p.wrench_terms.append(WrenchTerm(scale_law, [1.5], [0.0]))
        p.twist_terms.append(TwistTerm(lag_law, [0.01], np.zeros(6)))
    cc.compile()
    data = load_sequences(model.robot, 2, 40, seed=5)
    out = []
    for p in (py, cc):
        p.kinematics(np.radians(data.q_deg[0]))
        out.append([p.deflection(p.wrench_base(w.tolist()), 0.001) for w in data.wrench])
    assert close(out[1], out[0])
    assert cc.wrench_terms[0].state[0] == py.wrench_terms[0].state[0] == len(data)
    assert close(cc.twist_terms[0].state, py.twist_terms[0].state)
    # the lag does act: the last deflection trails the last static one
    static = FastPredictor(model)
    static.kinematics(np.radians(data.q_deg[0]))
    assert not close(out[0][-1], static.deflection(static.wrench_base((1.5 * data.wrench[-1]).tolist())))


def test_a_compiled_cycle_in_steady_state_allocates_nothing_that_stays(cfg):
    """sys.getallocatedblocks (every live block of Python's allocator) does not grow from one window of 1,500
    cycles to the next, after the tare, the reset and the payload switch's ramp (a cycle's lists and floats
    come from Python's free lists and go back to them)."""
    model = on_robot(model_with(*[e for entries in EXAMPLES.values() for e in entries[:1]]), "kr125_masses")
    cycle = Cycle.from_config(cfg, model)
    cycle.compensator.compile()
    run = drive(cycle, 15_000)
    for _ in range(11_500):                     # past the tare, the reset and the switch: steady state from here
        next(run)
    gc.collect()                                # (a full collection also empties the free lists ...)
    gc.disable()
    grown = []
    try:
        for _ in range(500):                    # (... which this refills)
            next(run)
        for _window in range(2):
            before = sys.getallocatedblocks()
            for _ in range(1500):
                next(run)
            grown.append(sys.getallocatedblocks() - before)
    finally:
        gc.enable()
    assert max(grown) <= 10, f"blocks that stayed per window of 1,500 cycles: {grown}"


def test_a_model_reload_ramps_alike_on_both_paths(cfg):
    """A reload's new predictor (compiled in the main thread, `service.reload`) is ramped in on the Python
    path, with each predictor's compiled form, and the compiled path takes over again after the ramp."""
    from service.model_ramp import PredictorRamp

    model = model_with(EXAMPLES["backlash"][0])
    d = model.to_dict()
    for e in d["effects"]:
        for key in e:
            if key.endswith(("_per_N", "_per_Nm")):
                e[key] *= 2.0
    doubled = StiffnessModel.from_dict(d, "doubled", robot=model.robot)
    py, cc = Cycle.from_config(cfg, model), Cycle.from_config(cfg, model)
    cc.compensator.compile()
    runs = [drive(py, 900), drive(cc, 900)]
    for step, _ in enumerate(zip(*runs)):
        if step == 100:                         # the reload's swap, as service.reload builds it
            for cycle in (py, cc):
                comp = cycle.compensator
                pred = FastPredictor.from_config(cfg.model, doubled)
                pred.carry(comp.gravity.mass, comp.gravity.cog, comp.gravity.g_mps2)
                pred.kinematics(comp.q_rad)
                if comp.kernel is not None:
                    pred.compile()

                def done(comp=comp, pred=pred):
                    comp.predictor = comp.payloads.predictor = pred

                comp.predictor = comp.payloads.predictor = PredictorRamp(comp.predictor, pred, 200, done)
        assert close(cc.deflection, py.deflection), (step, cc.deflection, py.deflection)
    assert cc.compensator.predictor.kernel is not None and cc.compensator.kernel.bound
