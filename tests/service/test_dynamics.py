"""The dynamic compensation in the service (`service.dynamics`, the parts of `stiffness.dynamics`).

* off by default: the shipped config adds no term;
* every part runs on the compiled path as on the Python one (rtol 1e-9 over a moving, tared, reset, loaded
  drive), the plan fed from the PLC's record;
* stability: 60 s of white-noise force at 1 kHz through the service's own cycle (compiled, in process, as fast
  as it runs), each part with its parameters 20 % off (the modes' frequencies, the horizon, the plan's force):
  no fault, and the correction does not grow (the last 20 s's RMS within 1.3 x the first 20 s's, no second's
  above 2 x), its RMS within 1.5 x what its own filters' gain allows over the static path's (`noise_gain`);
  the accelerometer's observer, with the box's noise too, within 1.5 x the same modes' RMS without it, and
  with its follower, which changes no frequency;
* the follower's frequencies (`Dynamics.retune`) reach the compiled cycle as the Python one; a follower whose
  structure lacks the observer's modes is refused with the config, naming the file and the key;
* the ramps and the faults: with the enable bit off the correction ramps to zero as the static one does; a
  correction that is not finite trips value_invalid and ramps; a fault reset restarts every state;
* the config: a feedforward whose value the register map lacks refuses to start, naming both; a reload
  that changes ``dynamics`` is refused (a restart applies it).
"""

from __future__ import annotations

import copy

import numpy as np
import pytest
from test_compiled_path import close, drive

from hil.testing import CONFIG, model_with
from plc_link.contract import FROM_PLC, Command, Fault, FromPlc
from service.app import Service
from service.ati import Reading
from service.config import ServiceConfig, load_config
from service.errors import ServiceConfigError
from service.pipeline import Cycle
from stiffness.files.yaml_schema import dump_yaml, read_yaml
from stiffness.model.stiffness_model import StiffnessModel

pytestmark = pytest.mark.slow

MODES = [{"hz": 10.0, "damping": 0.03, "direction": [1.0, 0.0, 0.0]},
         {"hz": 16.0, "damping": 0.03, "direction": [0.0, 1.0, 0.0]}]
PARTS = {
    "predictor": {"predictor": {"horizon_ms": 10.0}},
    "structure": {"structure": {"modes": MODES, "lag_ms": 4.0}},
    "feedforward": {"feedforward": {"source": "file", "file": "PLAN"}},
    "all": {"predictor": {}, "structure": {"modes": MODES, "lag_ms": 4.0},
            "feedforward": {"source": "file", "file": "PLAN"}},
    "observer": {"structure": {"modes": MODES, "lag_ms": 4.0}, "observer": {"modes": MODES, "horizon_ms": 5.0}},
    "follower": {"structure": {"modes": MODES, "lag_ms": 4.0},
                 "observer": {"modes": MODES, "horizon_ms": 5.0, "follow": True}},
}
BOUNDED_BY_THE_FORCE = sorted(set(PARTS) - {"observer", "follower"})     # driven by the acceleration too


def plan_file(folder, scale: float = 1.0):
    t = np.arange(0.0, 70.0, 0.01)
    e = np.clip((t % 2.0 - 0.5) / 0.1, 0.0, 1.0) * (t % 2.0 < 1.5)      # in and out of the material every 2 s
    path = folder / "plan.csv"
    np.savetxt(path, np.column_stack([t, e, np.tile(np.array([300.0, -200.0, 150.0]) * scale, (len(t), 1))]),
               delimiter=",", header="t_s,engagement,fx_N,fy_N,fz_N", comments="", fmt="%.5f")
    return path


def config_with(folder, part: str, scale: float = 1.0) -> ServiceConfig:
    cfg = load_config(CONFIG / "default.yaml")
    section = copy.deepcopy(PARTS[part])
    for sub in section.values():
        if sub.get("file") == "PLAN":
            sub["file"] = str(plan_file(folder, scale))
        for m in sub.get("modes", []):
            m["hz"] *= scale
        if "horizon_ms" in sub:
            sub["horizon_ms"] *= scale
    data = cfg.model_dump()
    data["dynamics"] = {"enabled": True, "delay_ms": 8.0, **section}
    if "observer" in section:
        data["accelerometer"] = {"enabled": True}
    out = ServiceConfig.model_validate(data)
    out.path = cfg.path
    out.tare.max_force_N = 2500.0
    return out


def inputs(t: float) -> FromPlc:
    """The PLC's record at ``t``: the plan's time, and a new accelerometer value each cycle (1 mg of noise about
    gravity along the box's z, the same at the same t)."""
    k = round(t * 1000.0)
    acc = np.random.default_rng(k).normal(0.0, 9.80665e-3, 3) + [0.0, 0.0, 9.81]
    return FromPlc(**{v.name: 0.0 for v in FROM_PLC})._replace(plan_time_s=t, acc_x=acc[0], acc_y=acc[1],
                                                               acc_z=acc[2], acc_samples=k % 65536)


@pytest.fixture(scope="module")
def model() -> StiffnessModel:
    return model_with()


def test_the_shipped_config_has_it_off(model):
    cycle = Cycle.from_config(load_config(CONFIG / "default.yaml"), model)
    fp = cycle.compensator.predictor
    assert cycle.compensator.dynamics is None and not fp.wrench_terms and not fp.twist_terms


@pytest.mark.parametrize("part", sorted(PARTS))
def test_every_part_runs_alike_on_the_compiled_and_the_python_path(tmp_path, model, part):
    cfg = config_with(tmp_path, part)
    py, cc = Cycle.from_config(cfg, model), Cycle.from_config(cfg, model)
    cc.compensator.compile()
    assert cc.compensator.predictor.kernel is not None
    static = Cycle.from_config(load_config(CONFIG / "default.yaml"), model)
    differs = False
    for k, _ in enumerate(zip(drive(py, 1500, plan=inputs), drive(cc, 1500, plan=inputs), drive(static, 1500))):
        assert close(cc.deflection, py.deflection), (k, cc.deflection, py.deflection)
        assert close(cc.correction, py.correction, 1e-7), (k, cc.correction, py.correction)
        differs |= not close(py.deflection, static.deflection, 1e-3)
    assert differs                      # the part does change the deflection


def test_the_followers_frequencies_reach_the_compiled_cycle_as_the_python_one(tmp_path, model):
    """`Dynamics.retune` (what the follower calls) mid-drive on both paths: they stay alike, and unlike a
    cycle that kept the configured modes."""
    cfg = config_with(tmp_path, "follower")
    py, cc, kept = (Cycle.from_config(cfg, model) for _ in range(3))
    cc.compensator.compile()
    differs = False
    for k, _ in enumerate(zip(drive(py, 1500, plan=inputs), drive(cc, 1500, plan=inputs),
                              drive(kept, 1500, plan=inputs))):
        if k == 700:
            for c in (py, cc):
                c.compensator.dynamics.retune([12.0, 19.0])
        assert close(cc.deflection, py.deflection), (k, cc.deflection, py.deflection)
        differs |= k > 700 and not close(py.deflection, kept.deflection, 1e-6)
    assert differs


@pytest.mark.parametrize("structure", [MODES[:1], None], ids=["one mode of two", "none"])
def test_a_follower_without_the_structures_modes_is_refused_naming_the_file_and_the_key(tmp_path, structure):
    data = read_yaml(CONFIG / "default.yaml")
    data["dynamics"] = {"enabled": True, "observer": {"modes": MODES, "follow": True}}
    if structure is not None:
        data["dynamics"]["structure"] = {"modes": structure}
    path = tmp_path / "service.yaml"
    path.write_text(dump_yaml(data, sort_keys=False))
    with pytest.raises(ServiceConfigError, match=rf"{path}: dynamics .*observer\.follow: .*dynamics\.structure"):
        load_config(path)


def white_noise_run(cycle: Cycle, seconds: float = 60.0, seed: int = 4) -> np.ndarray:
    """dq (deg, before limits) of every cycle under white-noise force (300 N, 30 Nm, 1 sigma) at fixed joints."""
    rng = np.random.default_rng(seed)
    n = int(seconds * 1000)
    noise = rng.normal(0.0, 1.0, (n, 6)) * [300.0, 300.0, 300.0, 30.0, 30.0, 30.0]
    q = [10.0, -70.0, 95.0, 15.0, 40.0, -20.0]
    enable = int(Command.ENABLE)
    out = np.empty((n, 6))
    for k in range(n):
        t = 0.001 * (k + 1)
        cycle.step(t, Reading(noise[k].tolist(), 0, k, False), [], enable, k, q, inputs=inputs(t))
        out[k] = cycle.dq_deg
    return out


@pytest.mark.parametrize("part", BOUNDED_BY_THE_FORCE)
def test_a_part_with_its_parameters_20_percent_off_stays_bounded_under_60_s_of_white_noise(tmp_path, model, part):
    cfg = config_with(tmp_path, part, scale=1.2)
    dyn, static = Cycle.from_config(cfg, model), Cycle.from_config(load_config(CONFIG / "default.yaml"), model)
    for c in (dyn, static):
        c.compensator.compile()
    dq, ref = white_noise_run(dyn), white_noise_run(static, seconds=10.0)
    assert dyn.faults.word == 0 and np.isfinite(dq).all()
    blocks = np.sqrt((dq[1000:].reshape(59, 1000, 6) ** 2).mean(axis=(1, 2)))     # 1 s blocks after the first
    # a lightly damped mode's response to noise varies from block to block (its band is 0.6 Hz wide); a part
    # that grew would leave any such bound by orders of magnitude
    assert blocks[-20:].mean() <= 1.3 * blocks[:20].mean() and blocks.max() <= 2.0 * blocks[:20].mean(), blocks
    bound = noise_gain(dyn) * np.sqrt((ref[1000:] ** 2).mean())
    # the bound treats the six channels alike (the modes act on the translation only, the predictor on all
    # six, the plan adds its own changes): a margin of 1.5 on it
    assert np.sqrt((blocks ** 2).mean()) <= 1.5 * bound, (blocks, bound)


def test_the_observer_with_its_modes_20_percent_off_stays_bounded_under_60_s_of_noise(tmp_path, model):
    """White-noise force and the box's noise (1 mg) together: no growth, and within 1.5 x the RMS of the same
    modes without the observer (the force-only path it corrects); with the follower too, which the noise gives
    nothing to follow (no frequency changed)."""
    runs, followers = {}, {}
    for part in ("observer", "follower", "structure"):
        cycle = Cycle.from_config(config_with(tmp_path, part, scale=1.2), model)
        cycle.compensator.compile()
        runs[part] = white_noise_run(cycle)
        followers[part] = cycle.compensator.dynamics.follower
        assert cycle.faults.word == 0 and np.isfinite(runs[part]).all()
    blocks = {p: np.sqrt((dq[1000:].reshape(59, 1000, 6) ** 2).mean(axis=(1, 2))) for p, dq in runs.items()}
    for part in ("observer", "follower"):
        b = blocks[part]
        assert b[-20:].mean() <= 1.3 * b[:20].mean() and b.max() <= 2.0 * b[:20].mean(), (part, b)
        assert np.sqrt((b ** 2).mean()) <= 1.5 * np.sqrt((blocks["structure"] ** 2).mean()), (part, blocks)
    assert all(m.changes == 0 for m in followers["follower"].modes)


def noise_gain(cycle: Cycle) -> float:
    """The RMS gain the dynamic terms may give white noise that has passed the service's low-pass, over the
    static path: sqrt(mean |P H B|^2 / mean |B|^2), P the predictor's response, H the largest of the modes'
    (1 without), B the low-pass's (each on the Nyquist band)."""
    f = np.linspace(0.0, 499.0, 4000)
    z = np.exp(-2j * np.pi * f / 1000.0)

    def biquad(c):
        return (c[0] + c[1] * z + c[2] * z * z) / (1.0 + c[3] * z + c[4] * z * z)

    comp = cycle.compensator
    B = np.prod([biquad(c) for c in comp.filter._coef], axis=0)
    gain = np.ones(len(f))
    for t in comp.predictor.wrench_terms:
        if len(t.params) == 5:               # the predictor (the feedforward's params start with a count)
            gain *= np.abs(biquad(t.params))
    for t in comp.predictor.twist_terms:
        n = int(t.params[0])
        gain *= np.max([np.abs(biquad(t.params[1 + 8 * k + 3:1 + 8 * k + 8])) for k in range(n)], axis=0)
    return float(np.sqrt(np.mean((gain * np.abs(B)) ** 2) / np.mean(np.abs(B) ** 2)))


def test_the_correction_ramps_and_the_faults_act_as_on_the_static_path(tmp_path, model):
    cfg = config_with(tmp_path, "all")
    cycles = {"dynamic": Cycle.from_config(cfg, model), "static": Cycle.from_config(load_config(CONFIG / "default.yaml"), model)}
    ramp_cycles = {}
    for name, c in cycles.items():
        c.compensator.compile()
        w, q = [300.0, -200.0, 150.0, 5.0, 2.0, 1.0], [10.0, -70.0, 95.0, 15.0, 40.0, -20.0]
        for k in range(1, 1500):
            c.step(0.001 * k, Reading(w, 0, k, False), [], int(Command.ENABLE), k, q, inputs=inputs(0.001 * k))
        before = np.abs(c.correction).max()
        assert before > 0
        n = 0
        while any(c.correction):          # the enable bit off: the ramp to zero
            k += 1
            n += 1
            c.step(0.001 * k, Reading(w, 0, k, False), [], 0, k, q, inputs=inputs(0.001 * k))
            assert np.abs(c.correction).max() <= before + 1e-12
            assert n < 1000
        ramp_cycles[name] = n
    assert abs(ramp_cycles["dynamic"] - ramp_cycles["static"]) <= 2 and ramp_cycles["static"] > 100
    c = cycles["dynamic"]
    comp = c.compensator
    terms = [*comp.predictor.wrench_terms, *comp.predictor.twist_terms]
    q = [10.0, -70.0, 95.0, 15.0, 40.0, -20.0]
    modes_params(comp, np.nan)              # a mode's coefficient spoilt: the correction is not finite
    start = k + 1
    for k in range(start, start + 300):
        c.step(0.001 * k, Reading([300.0, -200.0, 150.0, 5.0, 2.0, 1.0], 0, k, False), [], int(Command.ENABLE), k,
               q, inputs=inputs(0.001 * k))
    assert c.faults.word & int(Fault.VALUE_INVALID) and not any(c.correction)
    modes_params(comp, None)
    restarted = []
    for t in terms:                          # a fault reset restarts every state (`_StatefulTerm.reset`)
        t.reset = (lambda t=t, reset=t.reset: (restarted.append(t), reset()))
    k += 1
    c.step(0.001 * k, None, [], int(Command.ENABLE | Command.RESET), k, q, inputs=inputs(0.001 * k))
    assert restarted == terms and c.faults.word == 0


def modes_params(comp, value) -> None:
    """Set the last coefficient of the modes' term to ``value`` (None: back to its own), on both paths."""
    term = comp.predictor.twist_terms[-1]
    if not hasattr(term, "good"):
        term.good = term.params.copy()
    term.params[-1] = term.good[-1] if value is None else value
    kernel = comp.predictor.kernel
    if kernel is not None:
        kernel.tp[-1, len(term.params) - 1] = term.params[-1]


def test_a_feedforward_whose_value_the_map_lacks_refuses_to_start(tmp_path, model):
    cfg = config_with(tmp_path, "feedforward")
    cfg.plc.role, cfg.ads.enabled, cfg.monitoring.enabled = "none", False, False
    with pytest.raises(ServiceConfigError, match=r"dynamics.feedforward reads plan_time_s .* no register plan_time_s"):
        Service(cfg)


def test_the_observer_stays_off_when_the_accelerometers_values_come_every_4_ms(tmp_path, model, caplog):
    """A 200 Hz box read by a 2 ms task: values every 4-5 ms made the observer's correction worse than the static
    one's in the HIL (docs/accelerometer.md); it stays off, says so once, and the correction is the force-only
    path's, bit for bit."""
    import logging

    caplog.set_level(logging.WARNING, logger="stiffcomp.service")
    cycles = [Cycle.from_config(config_with(tmp_path, part), model) for part in ("observer", "structure")]
    w, q = [300.0, -200.0, 150.0, 5.0, 2.0, 1.0], [10.0, -70.0, 95.0, 15.0, 40.0, -20.0]
    for k in range(1, 800):
        t = 0.001 * k
        rec = inputs(t - 0.001 * (k % 4))._replace(acc_samples=k // 4)         # a new value every 4 ms
        for c in cycles:
            c.step(t, Reading(w, 0, k, False), [], int(Command.ENABLE), k, q, inputs=rec)
        assert cycles[0].correction == cycles[1].correction, k
    said = [r.getMessage() for r in caplog.records if "dynamics.observer" in r.getMessage()]
    assert len(said) == 1 and "every 4.0 ms" in said[0], said
