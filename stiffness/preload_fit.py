"""The identified preload in the fit: its start where the data step, and its lines in the fit's report
(`stiffness.preload`; `stiffness.identify` calls both)."""

from __future__ import annotations

import numpy as np

from .crossings import centre_search, centres, crossing_text
from .effects.axial import AxialEffect
from .model import StiffnessModel
from .preload import PreloadTerm, start_from_centres


def fresh_start(model, ctx, fit) -> None:
    """Start each identified preload still at its prior (beta = 0) where the data cross its joint's axial
    nonlinearity: `fit` the model without its axial effects and preloads, search the residual's steps per
    configuration (`centre_search`, the effect's own shape) and regress them (`start_from_centres`). In place."""
    fresh = [e for e in model.effects if isinstance(e, PreloadTerm) and not np.any(e.theta)]
    axial = {e.joint: e for e in model.effects if isinstance(e, AxialEffect)}
    fresh = [e for e in fresh if e.joint in axial]
    if not fresh:
        return
    plain = [e for e in model.effects if not isinstance(e, (PreloadTerm, AxialEffect))]
    if not plain:
        return
    base = StiffnessModel(model.robot, plain, noise=model.noise, source=model.source, payload=model.payload)
    result = fit(base, ctx, rounds=1, robust=False)
    model.bind_preload(ctx)
    for term in fresh:
        e = axial[term.joint]
        theta = e.theta.copy()
        if theta[0] == 0:
            theta[0] = 1.0                 # the shape, not the size, is searched
        tau_s, found = centre_search(ctx, result.residual, result.sigma, term.joint,
                                     lambda t, e=e, theta=theta: e.shape(t, theta))
        term.theta = start_from_centres(model, ctx, term, tau_s, found)


def notes(model, ctx) -> list[str]:
    """Per identified preload, in words: where each configuration crosses (or only bounds) the static
    torque, and how many combinations of its base parameters the data leave at their prior."""
    out = []
    for term in (e for e in model.effects if isinstance(e, PreloadTerm)):
        model.bind_preload(ctx)
        first = np.unique(ctx.config, return_index=True)[1]
        seen = int(np.linalg.matrix_rank(term.phi(ctx)[first], tol=1e-6)) if len(term.columns) else 0
        has_axial = any(isinstance(e, AxialEffect) and e.joint == term.joint for e in model.effects)
        where = crossing_text(ctx, term.joint, centres(model, ctx, term.joint)) if has_axial else \
            "no axial nonlinearity at this joint to locate it"
        out.append(f"static torque of joint {term.joint} identified: {where}; the configurations see {seen} of its "
                   f"{len(term.columns)} base parameters, the other {len(term.columns) - seen} combination(s) "
                   "stay at the prior (the robot's masses, or zero without them)")
    return out
