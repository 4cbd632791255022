"""Every effect of the library runs in the service's fast path and agrees with `StiffnessModel.predict`.

Parameterised over the effect registry (`stiffness.effects.EFFECTS`): a new effect without an example
here, or without a real-time term of its own (`Effect.realtime`), fails.

Each case: the axial-spring model plus the effect, random configurations, and in each a random load
sequence (a random walk of the wrench with reversals, in time order), the fast path stepped through it
as the service does (history restarted at each configuration, like a tare). Tolerances:

* against ``predict(linear=True)``: the fast path is the same first-order model, so the agreement is
  to rounding (rtol 1e-9);
* against ``predict`` (the loaded chain composed with finite rotations): they differ by the
  second-order terms, |delta|^2 relative to |delta| with joint twists of ~1e-3 rad, so 2e-3 of the
  largest component;
* the correction: with three Newton refinements, the TCP at q + δq sits where the unloaded TCP would
  be moved by minus the *exact* deflection, to 5e-3 of |dX| (the 2e-3 above, plus the change of the
  deflection between q and q + δq, which is of the order of δq ~ 1e-3 rad).

Drift is ignored by the service (docs/service.md): its case expects the model without drift.
"""

from __future__ import annotations

import numpy as np
import pytest

from hil.testing import CONFIG, model_with
from service.compensation import FastPredictor
from stiffness.data.measurements import Dataset
from stiffness.effects import EFFECTS, Effect
from testlib.common import pose_error

# one or more entries per library effect, sized so each matters against the springs
EXAMPLES: dict[str, list[dict]] = {
    "joint_spring": [{"effect": "joint_spring", "joint": 2, "x_m_per_N": 2e-8, "ry_rad_per_Nm": 1e-7}],
    "joint_6dof": [{"effect": "joint_6dof", "joint": 4, "x_m_per_N": 1e-8, "y_m_per_N": 1e-8,
                    "rx_rad_per_Nm": 3e-7, "ry_rad_per_Nm": 3e-7}],
    "backlash": [{"effect": "backlash", "joint": 2, "lost_motion_deg": 0.02, "width_Nm": 50.0}],
    "hysteresis": [{"effect": "hysteresis", "joint": 2, "offset_deg": -0.01, "transition_Nm": 60.0},
                   {"effect": "hysteresis", "joint": 4, "offset_deg": 0.01, "transition_Nm": 0.0,
                    "threshold_Nm": 5.0}],
    "nonlinear_stiffness": [{"effect": "nonlinear_stiffness", "joint": 3, "form": "two_slope",
                             "soft_rad_per_Nm": 1e-7, "knee_Nm": 300.0}],
    "link_bending": [{"effect": "link_bending", "link": 2, "compliance_per_Nm2": 3e-7},
                     {"effect": "link_bending", "link": 3, "compliance_per_Nm2": 3e-7},
                     {"effect": "link_bending", "link": 5, "compliance_per_Nm2": 5e-6}],
    "sensor_misalignment": [{"effect": "sensor_misalignment", "rx_deg": 1.5, "ry_deg": -1.0, "rz_deg": 3.0}],
    "drift": [{"effect": "drift", "x_mm_per_min": 0.05, "rz_deg_per_min": 0.002}],
}
IGNORED = {"drift"}
CASES = [pytest.param(name, k, id=f"{name}-{k}") for name in sorted(EFFECTS)
         for k in range(max(1, len(EXAMPLES.get(name, []))))]


def load_sequences(robot, configs: int, steps: int, seed: int) -> Dataset:
    """``configs`` random configurations, each with a random walk of ``steps`` wrenches, in time order."""
    rng = np.random.default_rng(seed)
    lim = robot.limits_deg
    q = rng.uniform(lim[:, 0] * 0.9, lim[:, 1] * 0.9, size=(configs, 6))
    scale = np.array([800, 800, 800, 80, 80, 80])
    w = np.cumsum(rng.uniform(-1, 1, size=(configs, steps, 6)) * scale, axis=1)
    n = configs * steps
    return Dataset(np.tile(np.arange(steps, dtype=float), configs), np.repeat([f"c{k}" for k in range(configs)], steps),
                   np.repeat(q, steps, axis=0), w.reshape(n, 6), np.full(n, 6), np.zeros((n, 6)))


def run_fast(fp: FastPredictor, data: Dataset, steps: int, correct: bool = False):
    """The fast path through each configuration's sequence; deflections (N, 6) mm, deg, and pose errors."""
    out, errs = [], []
    for start in range(0, len(data), steps):
        qr = np.radians(data.q_deg[start])
        fp.reset_history()
        fp.kinematics(qr)
        for k in range(start, start + steps):
            dX = fp.deflection(fp.wrench_base(data.wrench[k].tolist()))
            out.append(np.concatenate([dX[:3] * 1000.0, np.degrees(dX[3:])]))
            if correct:
                errs.append(fp.correction(qr, dX))
    return np.array(out), errs


@pytest.mark.parametrize("name, k", CASES)
def test_fast_path_agrees_with_the_model(name, k):
    assert EFFECTS[name].realtime is not Effect.realtime or EFFECTS[name].kind == "input", \
        f"effect {name} has no real-time term (Effect.realtime)"
    assert EXAMPLES.get(name), f"effect {name} needs an example in this test"
    entry = EXAMPLES[name][k]
    model = model_with(entry)
    steps = 12
    data = load_sequences(model.robot, 8, steps, seed=100 + 7 * k + len(name))
    fp = FastPredictor(model, damping=1e-6, refinement_iterations=3)
    got, dqs = run_fast(fp, data, steps, correct=True)
    expected_model = model_with() if name in IGNORED else model
    assert fp.ignored == ([model.effects[-1].label] if name in IGNORED else [])
    linear, exact = expected_model.predict(data, linear=True), expected_model.predict(data)
    np.testing.assert_allclose(got, linear, rtol=1e-9, atol=1e-12)
    for g, e in zip(got, exact):
        np.testing.assert_allclose(g, e, atol=2e-3 * np.abs(e).max())
    # the correction undoes the exact deflection
    for i, dq in enumerate(dqs):
        dX = np.concatenate([exact[i, :3] / 1000.0, np.radians(exact[i, 3:])])
        qr = np.radians(data.q_deg[i])
        assert pose_error(fp, qr, dq, dX) <= 5e-3 * np.linalg.norm(dX)
    # and the effect does contribute (against the springs alone), except where it is ignored
    springs, _ = run_fast(FastPredictor(model_with()), data, steps)
    moved = np.abs(got - springs).max(axis=1) > 1e-6 * np.abs(springs).max()
    assert moved.mean() == (0.0 if name in IGNORED else pytest.approx(1.0, abs=0.15))


def test_hysteresis_state_restarts_on_tare_and_fault_reset():
    """In the running cycle the loading state is 0 again after a tare and after a fault reset."""
    from plc_link.contract import Command
    from service.ati import Reading
    from service.config import load_config
    from service.pipeline import Cycle

    model = model_with(EXAMPLES["hysteresis"][0])
    cfg = load_config(CONFIG / "default.yaml")
    cfg.tare.max_force_N = 2500.0           # this test tares under load on purpose (the history restarts)
    cycle = Cycle.from_config(cfg, model)
    state = cycle.compensator.predictor.history[0].state      # [z, reference, direction, started]
    q = [10.0, -70.0, 95.0, 15.0, 40.0, -20.0]
    hb = 0

    def step(t, fx, command=0):
        nonlocal hb
        hb += 1
        cycle.step(t, Reading([fx, 0.0, 200.0, 0.0, 0.0, 0.0], 0, hb, False), [], command, hb, q)

    t = 0.0
    for fx in np.linspace(0.0, 900.0, 200):           # a load rising: z leaves 0
        t += 0.001
        step(t, fx)
    assert abs(state[0]) > 0.5
    step(t + 0.001, 900.0, int(Command.TARE))
    step(t + 0.002, 900.0)
    assert state[0] == 0.0 and state[3] == 1.0          # restarted at the tare, the new torque its reference
    for fx in np.linspace(900.0, 0.0, 200):
        t += 0.001
        step(t + 0.002, fx)
    assert abs(state[0]) > 0.5
    step(t + 0.003, 0.0, int(Command.RESET))
    assert state[0] == 0.0


def test_bending_formed_per_kinematics_equals_the_constant_one():
    """A robot whose beam changes with q recomputes C at every kinematics; on the KR 125 both routes agree."""
    model = model_with(*EXAMPLES["link_bending"])
    fast, slow = FastPredictor(model), FastPredictor(model)
    assert all(b.constant for b in fast.frame_terms)
    slow.slow_frame_terms = list(slow.frame_terms)
    for b in slow.frame_terms:
        b.C = np.full((6, 6), np.nan)               # only kinematics() can make it usable again
    data = load_sequences(model.robot, 6, 1, seed=3)
    for q, w in zip(data.q_deg, data.wrench):
        for fp in (fast, slow):
            fp.kinematics(np.radians(q))
        np.testing.assert_allclose(slow.deflection(slow.wrench_base(w.tolist())),
                                   fast.deflection(fast.wrench_base(w.tolist())), rtol=1e-9, atol=1e-15)
