"""The identified preload in the fit: its start where the data step, whether the data support it, and
its lines in the fit's report (`stiffness.model.preload_term`; `stiffness.fit.identify` calls them).

A preload is called identified only when the data show its joint's crossing: the fitted model's
residual, against the same model without that joint's axial nonlinearity and its preload (the other
parameters held, the linear ones solved again), must move by more than the noise allows. With chi^2
the sum of the squared weighted residuals over n measured entries, the RMS is sqrt(chi^2 / n) and,
noise alone, its relative spread is 1 / sqrt(2 n); the crossing counts when

    1 - sqrt(chi^2_with / chi^2_without)  >  Z_NOISE / sqrt(2 n).

(A chi^2 test of the nested models would assume every residual independent; repeated readings, bodies
on one arm and the six components of a reading are not, and the test then passes for any nonlinearity
that fits a little of the noise.)
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ..data.crossings import centre_search, centres, crossing_text
from ..effects.axial import AxialEffect
from ..model.preload_term import PreloadTerm, start_from_centres
from ..model.stiffness_model import StiffnessModel


def fresh_start(model, ctx, fit, say: Callable[[str], None] = lambda stage: None) -> None:
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
    say(f"starting the static torque of joint(s) {', '.join(str(e.joint) for e in fresh)} where the data step")
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


Z_NOISE = 3.0           # the RMS must move by this many of its own noise spreads for a crossing to count


class Evidence(NamedTuple):
    """What the data say of joint ``joint``'s identified preload (`evidence`)."""

    joint: int
    identified: bool
    moved: float | None     # 1 - RMS with / RMS without the joint's nonlinearity and preload; None: none there
    allowed: float          # Z_NOISE / sqrt(2 n): what the noise alone moves it by

    def to_dict(self) -> dict:
        return self._asdict()


def evidence(model, ctx, y: np.ndarray, w: np.ndarray, resid: np.ndarray,
             resolve: Callable) -> list[Evidence]:
    """Per identified preload: does the fit's RMS move by more than the noise allows (module docstring)?

    ``y``, ``w``, ``resid`` (N, 6): the measured deflection, the fit's weights and residual;
    ``resolve(reduced_model, theta)``: theta with the reduced model's linear parameters solved again."""
    out = []
    chi_with = float(np.nansum((resid * w) ** 2))
    n = max(int(np.count_nonzero(w)), 1)
    allowed = Z_NOISE / np.sqrt(2.0 * n)
    for term in [e for e in model.effects if isinstance(e, PreloadTerm)]:
        gone = [e for e in model.effects if e.joint == term.joint and isinstance(e, (AxialEffect, PreloadTerm))]
        if len(gone) == 1:              # no nonlinearity at this joint: nothing to cross
            out.append(Evidence(term.joint, False, None, float(allowed)))
            continue
        reduced = StiffnessModel(model.robot, [e for e in model.effects if e not in gone], noise=model.noise,
                                 source=model.source, payload=model.payload)
        theta = resolve(reduced, reduced.theta)
        chi_without = float(np.nansum(((y - reduced.predict(ctx, theta)) * w) ** 2))
        moved = 1.0 - np.sqrt(chi_with / chi_without) if chi_without > 0 else 0.0
        out.append(Evidence(term.joint, bool(moved > allowed), float(moved), float(allowed)))
    model.bind_preload(ctx)
    return out


def notes(model, ctx, found: list[Evidence]) -> list[str]:
    """Per identified preload, in words: where each configuration crosses (or only bounds) the static
    torque, and how many combinations of its base parameters the data leave at their prior; or that the
    data show no crossing (``found``, `evidence`)."""
    out = []
    model.bind_preload(ctx)
    for term, ev in zip((e for e in model.effects if isinstance(e, PreloadTerm)), found):
        if not ev.identified:
            why = ("no axial nonlinearity at this joint (an effect at the total torque) to cross" if ev.moved is None else
                   f"its nonlinearity and preload move the residual RMS by {100 * ev.moved:.2f} %, no more than "
                   f"the noise allows ({100 * ev.allowed:.2f} %)")
            out.append(f"static torque of joint {term.joint} not identified: the data show no crossing at this "
                       f"joint ({why}); the fitted preload values are not supported by the data, keep the prior "
                       "(remove the model's preload entry for this joint)")
            continue
        first = np.unique(ctx.config, return_index=True)[1]
        seen = int(np.linalg.matrix_rank(term.phi(ctx)[first], tol=1e-6)) if len(term.columns) else 0
        where = crossing_text(ctx, term.joint, centres(model, ctx, term.joint))
        out.append(f"static torque of joint {term.joint} identified: {where} (the residual RMS moves by "
                   f"{100 * ev.moved:.1f} %, the noise alone {100 * ev.allowed:.2f} %); the configurations see "
                   f"{seen} of its {len(term.columns)} base parameters, the other {len(term.columns) - seen} "
                   "combination(s) stay at the prior (the robot's masses, or zero without them)")
    return out
