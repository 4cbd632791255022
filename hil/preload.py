"""The HIL's preloaded backlash: a truth that carries its own weight, and the service compensating it
with a model that knows the preload and with one that does not.

The truth is examples/truth_reference.yaml plus a backlash at joint 2 (`PRELOADED_BACKLASH`) on
config/robots/kr125_masses.yaml (the KR 125's approximate masses, a balancer carrying 0.6 of joint 2's
static torque), with the scenario's 12 kg spindle at the sensor: its play sits at zero *total* torque
tau_s(q) + tau_ext. The circle is milled at `UPRIGHT_Q_DEG`, where the process crosses that play at an
external -200 to -300 Nm (hil_tests/test_hil_preload.py says why this pose).

* ``aware``: the truth itself; the service forms tau_s from its robot and the ``gravity`` section.
* ``blind``: the same springs and backlash on config/robots/kr125.yaml (no masses, tau_s = 0): the
  play at zero *external* torque, as the library modelled it before robots had masses.

Used by the test and by benchmarks/bench_hil_preload.py, which reports the figures of docs/hil.md.
"""

from __future__ import annotations

from pathlib import Path

from stiffness.effects.backlash import Backlash
from stiffness.model.stiffness_model import StiffnessModel

from .report import errors, evaluate_pass, evaluate_uncompensated
from .robot_stub import RobotStub
from .run import run_pass
from .scenario import Scenario, load_scenario
from .testing import CONFIG, truth_with
from .world import World

MASSES = CONFIG / "robots" / "kr125_masses.yaml"
UPRIGHT_Q_DEG = [0.0, -90.0, 90.0, 0.0, 90.0, 0.0]      # the arm upright, the tool down, 0.78 m above joint 2
# 1.8 arcmin of lost motion (a worn or loosely set gearbox), a step on the scale of the process force
PRELOADED_BACKLASH = {"effect": Backlash.name, "joint": 2, "lost_motion_deg": 0.03, "width_Nm": 10.0}
FEED_MM_S = 60.0                                        # a 3.7 s circle


def preload_scenario() -> Scenario:
    """config/hil/circle.yaml at `UPRIGHT_Q_DEG` and `FEED_MM_S` (its payload: the 12 kg spindle)."""
    sc = load_scenario()
    sc.circle.center_q_deg = list(UPRIGHT_Q_DEG)
    sc.circle.feed_mm_s = FEED_MM_S
    return sc


def preload_models() -> dict[str, StiffnessModel]:
    """{"aware": the truth with masses, "blind": the same effects on the robot without masses}."""
    return {"aware": truth_with([PRELOADED_BACKLASH], robot=MASSES), "blind": truth_with([PRELOADED_BACKLASH])}


def preload_path_errors(folder: Path) -> dict[str, dict]:
    """Mill the circle once per model (one service run each) and return
    ``{"mean_error_mm": {uncompensated, aware, blind}, "max_error_mm": {...}, "cycles": {...},
    "exceed_count": {...}}``; the uncompensated error is the truth's deflection along the nominal
    path (`evaluate_uncompensated`, no process)."""
    sc = preload_scenario()
    models = preload_models()
    truth = models["aware"]
    truth_path = Path(folder) / "truth.yaml"
    truth.to_yaml(truth_path)
    stub = RobotStub(truth, sc.robot, sc.payload)
    evals = {"uncompensated": evaluate_uncompensated(World(sc, truth.robot), stub, sc.plc.period_ms / 1e3)}
    out: dict[str, dict] = {"cycles": {}, "exceed_count": {}}
    for name, model in models.items():
        path = truth_path if name == "aware" else Path(folder) / f"{name}.yaml"
        if name != "aware":
            model.to_yaml(path)
        r = run_pass(sc, truth, path, True, Path(folder) / name)
        evals[name] = evaluate_pass(sc, truth, r)[1]
        out["cycles"][name] = int(r.stats[-1].get("cycles", 0))
        out["exceed_count"][name] = int(r.stats[-1].get("exceed_count", 0))
    figures = {k: errors(ev) for k, ev in evals.items()}
    out["mean_error_mm"] = {k: v[0] for k, v in figures.items()}
    out["max_error_mm"] = {k: v[1] for k, v in figures.items()}
    return out
