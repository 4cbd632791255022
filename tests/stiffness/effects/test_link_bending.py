"""link_bending: the Euler-Bernoulli cantilever at the link's tip."""

import numpy as np
from effect_helpers import context

from stiffness.effects.link_bending import LinkBending


def tip_quantities(ctx, e):
    tip = e.tip_frame(ctx.F[0])
    Ft, Fr = ctx.F[:, tip], ctx.F[:, e.joint - 1]
    axis = Ft[:, :3, 3] - Fr[:, :3, 3]
    L = np.linalg.norm(axis, axis=1)
    u = np.einsum("rji,rj->ri", Ft[:, :3, :3], axis / L[:, None])
    return tip, L, u


def test_tip_force_and_moment_give_the_cantilever_formulas(robot):
    ctx = context(robot, n=10)
    c = 1e-7
    e = LinkBending(2, c)
    tip, L, u = tip_quantities(ctx, e)
    assert tip == 2 and np.allclose(L, 1.0)                  # the upper arm: a2 = 1000 mm
    perp = np.cross(u, [0.3, 0.5, 0.8])
    perp /= np.linalg.norm(perp, axis=1)[:, None]
    W = np.zeros((ctx.n_readings, 7, 6))
    W[:, tip, :3] = 1000.0 * perp                            # 1 kN across the beam
    tw = e.twists(ctx, e.theta, W)[:, 5 + tip]
    np.testing.assert_allclose(tw[:, :3], c * L[:, None] ** 3 / 3 * 1000.0 * perp, rtol=1e-12)
    np.testing.assert_allclose(tw[:, 3:], c * L[:, None] ** 2 / 2 * 1000.0 * np.cross(u, perp), rtol=1e-12)
    W[:, tip, :3] = 1000.0 * u                               # along the beam: no bending
    assert np.abs(e.twists(ctx, e.theta, W)).max() < 1e-15
    W[:, tip, :3] = 0.0
    W[:, tip, 3:] = 100.0 * perp                             # a bending moment
    tw = e.twists(ctx, e.theta, W)[:, 5 + tip]
    np.testing.assert_allclose(tw[:, 3:], c * L[:, None] * 100.0 * perp, rtol=1e-12)
    np.testing.assert_allclose(tw[:, :3], c * L[:, None] ** 2 / 2 * 100.0 * np.cross(perp, u), rtol=1e-12)


def test_link3_bends_as_the_forearm(robot):
    """Link 3's DH length is the 45 mm elbow offset; the beam runs to the wrist centre (frame 4)."""
    ctx = context(robot, n=5)
    tip, L, _ = tip_quantities(ctx, LinkBending(3))
    assert tip == 4
    np.testing.assert_allclose(L, np.hypot(0.045, 1.0))


def test_a_link_of_no_length_does_not_bend(tmp_path):
    """A robot whose link 5 has neither a nor d (and link 6 none either): zero twist, no NaN."""
    import yaml

    from stiffness.data.campaign import Context
    from stiffness.kinematics.robot import Robot
    from testlib.common import ROOT, random_dataset

    d = yaml.safe_load((ROOT / "config/robots/kr125.yaml").read_text())
    d["dh"]["d_mm"][5] = 0.0
    (tmp_path / "r.yaml").write_text(yaml.safe_dump(d))
    robot = Robot.from_yaml(tmp_path / "r.yaml")
    ctx = Context(robot, random_dataset(robot, 5, 0))
    e = LinkBending(5, 1e-7)
    tw = e.twists(ctx, e.theta, ctx.frame_wrench)
    assert np.isfinite(tw).all() and np.abs(tw).max() == 0.0
