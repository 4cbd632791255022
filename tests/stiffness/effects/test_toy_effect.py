"""A new effect is one file plus its test (issue 18): a toy effect defined here, in this module only, is
fitted, diagnosed, described and compensated in the service's cycle, with no other file touched.

The toy: a constant turn c of joint i's axis whenever the arm is measured, delta_rz,i = c. It is
registered for the test alone (`EFFECTS` is the one registry every part of the project reads). Its law is
a plain numeric function of this module (`offset_law`), which the service compiles into the cycle
(issue 25): the cycle here runs compiled, and agrees with the model.
"""

from __future__ import annotations

import numpy as np
import pytest
from discovery.campaigns import campaign, start_model

from hil.testing import CONFIG, truth_with
from service.compensation import FastPredictor
from service.config import load_config
from service.pipeline import Cycle
from stiffness.data.measurements import Dataset
from stiffness.diagnose.discovery import diagnose
from stiffness.effects import EFFECTS
from stiffness.effects.axial import axial_basis
from stiffness.effects.base import Effect, Param, read_location, read_values
from stiffness.effects.terms import AxialTerm
from stiffness.fit.identify import fit
from stiffness.model.edit import add_effect
from stiffness.model.stiffness_model import StiffnessModel
from stiffness.units import RAD_TO_DEG

pytestmark = pytest.mark.slow

NOISE_MM, NOISE_DEG = 0.03, 0.002
TRUE_OFFSET_DEG = 0.01


def offset_law(tau, p):
    """delta_rz = c, p = [c (rad)]: the toy's equation, for the Python and the compiled cycle."""
    return p[0]


class JointOffset(Effect):
    """A constant turn of joint i's axis: delta_rz,i = c (YAML: offset_deg, deg).

    >>> JointOffset(2, np.radians(0.01)).realtime(robot=None)[0].f(123.0) == np.radians(0.01)
    True
    """

    name = "toy_joint_offset"
    equation = "delta_rz,i = c"
    examples = ({"effect": "toy_joint_offset", "joint": 2, "offset_deg": TRUE_OFFSET_DEG},)

    def __init__(self, joint: int, offset_rad: float = 0.0):
        super().__init__([Param("offset_deg", "deg", 1e-4, yaml_factor=RAD_TO_DEG)], np.array([offset_rad]), joint)

    @classmethod
    def from_config(cls, section, robot, where) -> JointOffset:
        joint = read_location(section, "joint", cls.joints, where)
        return cls(joint, read_values(cls.name, section, cls(joint).params, where, ("joint",))[0])

    def basis(self, ctx, W, theta):
        return axial_basis(ctx, self.joint, [np.ones(len(W))])

    def realtime(self, robot):
        return [AxialTerm(self.joint, law=offset_law, params=[self.theta[0]])]

    @classmethod
    def candidates(cls, model, ctx):
        return [[cls(j)] for j in cls.joints if not model.has(cls.name, j)]

    def size_text(self, estimate, std_error, model) -> str:
        return f"a constant turn of {estimate[0] * RAD_TO_DEG:+.4f} deg (± {std_error[0] * RAD_TO_DEG:.4f})"


@pytest.fixture
def toy(monkeypatch):
    monkeypatch.setitem(EFFECTS, JointOffset.name, JointOffset)
    return JointOffset


def test_the_toy_is_diagnosed_described_fitted_and_compensated(toy):
    truth = truth_with(list(toy.examples))
    data = campaign(truth, seed=31, configs=4)
    # diagnosed and described in its own words
    d = diagnose(start_model(), data)
    assert d.verdict == "missing_effect", d.message
    assert (d.best.name, d.best.joint) == (toy.name, 2), [(c.name, c.joint) for c in d.candidates[:3]]
    assert d.best.explanation.startswith(f"Missing: {toy.name} at joint 2, a constant turn of +0.01")
    # added and fitted: the residual falls to the noise, the offset comes back
    fixed = fit(add_effect(d.fit.model, toy.name, 2), data)
    assert fixed.rms_position_mm <= 1.15 * NOISE_MM
    assert fixed.rms_rotation_deg <= 1.15 * NOISE_DEG
    (offset,) = [e for e in fixed.model.effects if e.name == toy.name]
    assert offset.theta[0] * RAD_TO_DEG == pytest.approx(TRUE_OFFSET_DEG, rel=0.05)
    # written and read back through the registry
    again = StiffnessModel.from_dict(fixed.model.to_dict(), "toy.yaml", robot=fixed.model.robot)
    np.testing.assert_allclose(again.theta, fixed.model.theta, rtol=1e-5)
    # compensated in the compiled cycle: the fast path equals the model's first-order prediction, toy included
    fp = FastPredictor(fixed.model)
    fp.compile()
    compiled_laws = [getattr(v, "py_func", None) for v in vars(fp.kernel.mod).values()]
    assert offset_law in compiled_laws                  # the toy's own law, compiled into the cycle
    without = FastPredictor(StiffnessModel(fixed.model.robot, [e for e in fixed.model.effects if e is not offset]))
    rows = np.arange(0, len(data), 97)
    sub = Dataset(data.time_s[rows], data.config[rows], data.q_deg[rows], data.wrench[rows], np.full(len(rows), 6),
                  np.zeros((len(rows), 6)))            # the TCP (body 6), as the cycle corrects it
    linear = fixed.model.predict(sub, linear=True)
    for k in range(len(sub)):
        for p in (fp, without):
            p.kinematics(np.radians(sub.q_deg[k]))
        dX = fp.deflection(fp.wrench_base(sub.wrench[k].tolist()))
        np.testing.assert_allclose(np.concatenate([dX[:3] * 1e3, np.degrees(dX[3:])]), linear[k],
                                   rtol=1e-9, atol=1e-12)
        assert np.abs(dX - without.deflection(without.wrench_base(sub.wrench[k].tolist()))).max() > 1e-6


def test_the_running_cycle_starts_with_the_toy_and_corrects_by_it(toy):
    """The service's own cycle, from its config: the toy's turn reaches the joint correction."""
    cfg = load_config(CONFIG / "default.yaml")
    base = StiffnessModel.from_yaml(CONFIG / "models" / "kr125_6dof.yaml")
    with_toy = StiffnessModel.from_dict({**base.to_dict(), "effects": base.to_dict()["effects"]
                                         + list(toy.examples)}, "toy.yaml", robot=base.robot)
    q = [10.0, -70.0, 95.0, 15.0, 40.0, -20.0]
    out = []
    for model in (base, with_toy):
        comp = Cycle.from_config(cfg, model).compensator
        comp.compile()                                      # the cycle as the service runs it: compiled
        p = comp.predictor
        assert p.kernel is not None
        p.kinematics(np.radians(q))
        out.append(p.correction(np.radians(q), p.deflection(p.wrench_base([300.0, 0, 200.0, 0, 0, 0]))))
    # the toy turns joint 2 by +c: the correction turns it back (other joints hold the TCP's pose)
    assert out[1][1] - out[0][1] == pytest.approx(-np.radians(TRUE_OFFSET_DEG), rel=0.05)
