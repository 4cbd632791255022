"""Path accuracy and path repeatability as ISO 9283 defines them (sections 8.2 and 8.3): the robot follows the
same commanded path n times, and at each of m points c_i along it the n attained points x_ij are taken where
each attained path crosses the plane normal to the commanded path at c_i.

The barycentre of the attained points in plane i, and path accuracy (the largest distance between the
commanded path and the barycentre line):

    x̄_i = (1/n) sum_j x_ij
    AT_p = max_i |x̄_i - c_i|

Path repeatability (the largest spread of the attained paths about their barycentre line), from the distances
of the attained points to their barycentre, their mean and their standard deviation (n - 1 in the
denominator, as the standard's pose repeatability):

    l_ij = |x_ij - x̄_i|,    l̄_i = (1/n) sum_j l_ij,    S_li = sqrt(sum_j (l_ij - l̄_i)^2 / (n - 1))
    RT_p = max_i (l̄_i + 3 S_li)                         (n >= 2; none for one path)

For the HIL's circle the plane normal to the path at angle phi holds the circle's axis and its radius at
phi, so an attained path crosses it where its own angle about the circle's centre reaches phi (`in_planes`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from .report import Evaluation


@dataclass
class PathFigures:
    """AT_p and RT_p (the units of the points; RT_p None with one path) and where each is largest, as the
    label of that point (`path_figures`' ``at``: the circle's angle in degrees for `circle_figures`)."""

    accuracy: float
    repeatability: float | None
    worst_accuracy_at: float
    worst_repeatability_at: float | None


def path_figures(commanded: np.ndarray, attained: np.ndarray, at: np.ndarray | None = None) -> PathFigures:
    """AT_p and RT_p of ``attained`` (n, m, 3): n paths, each at the m normal planes of ``commanded`` (m, 3).
    ``at`` (m,): what a user reads each plane by (an angle, a distance along the path); the planes' index
    where not given."""
    x = np.asarray(attained, dtype=float)
    c = np.asarray(commanded, dtype=float)
    if x.ndim != 3 or x.shape[1:] != c.shape or x.shape[0] < 1:
        raise ValueError(f"attained {x.shape} must be (n, m, 3) at the commanded points {c.shape}")
    label = np.arange(len(c), dtype=float) if at is None else np.asarray(at, dtype=float)
    if label.shape != (len(c),):
        raise ValueError(f"at {label.shape} must label the {len(c)} commanded points")
    bary = x.mean(axis=0)
    at_p = np.linalg.norm(bary - c, axis=1)
    if len(x) < 2:
        return PathFigures(float(at_p.max()), None, float(label[at_p.argmax()]), None)
    spread = np.linalg.norm(x - bary, axis=2)                        # l_ij, (n, m)
    rt = spread.mean(axis=0) + 3.0 * spread.std(axis=0, ddof=1)
    return PathFigures(float(at_p.max()), float(rt.max()), float(label[at_p.argmax()]), float(label[rt.argmax()]))


def cut_by_angle(evaluation: Evaluation) -> tuple[np.ndarray, np.ndarray]:
    """The cut's actual TCP (base, m) in time order and its angle about the circle's centre, unwrapped and
    starting near 0 (``evaluation``: `hil.report.evaluate`'s)."""
    cut = evaluation.cut
    order = np.argsort(evaluation.t[cut])
    ang = np.unwrap(evaluation.angle[cut][order])
    ang -= 2 * np.pi * np.round(ang[0] / (2 * np.pi))       # the start near 0, not near 2 pi
    return ang, evaluation.p[cut][order]


def in_planes(path, evaluation: Evaluation, phi: np.ndarray) -> np.ndarray:
    """Where the cut's path first crosses the plane normal to the circle ``path`` (`hil.path.CirclePath`: its
    plane the base's xy) at each angle ``phi`` (m,): (m, 3), NaN where the cut never reaches that angle.
    Between two cycles the TCP's distance from the circle's axis and its height go linearly with its angle, so
    a gap in the log (a host that stalled) does not cut the corner a straight chord would."""
    ang, p = cut_by_angle(evaluation)
    reached = np.maximum.accumulate(ang)                   # the first crossing of phi is where this passes it
    k = np.searchsorted(reached, phi, side="left")
    out = np.full((len(phi), 3), np.nan)
    ok = (k > 0) & (k < len(ang))
    k = k[ok]
    w = (phi[ok] - ang[k - 1]) / (ang[k] - ang[k - 1])
    d = p - path.center
    rho, z = np.hypot(d[:, 0], d[:, 1]), d[:, 2]
    r = rho[k - 1] + w * (rho[k] - rho[k - 1])
    h = z[k - 1] + w * (z[k] - z[k - 1])
    out[ok] = path.center + r[:, None] * path.outward(phi[ok]) + h[:, None] * np.array([0.0, 0.0, 1.0])
    return out


def circle_figures(path, evaluations: list[Evaluation], points: int) -> PathFigures:
    """AT_p and RT_p (mm) of the repeats of one pass (their evaluations) about the commanded circle ``path``
    (`hil.path.CirclePath`), at ``points`` angles equally spaced round it that every repeat reaches; where each
    is largest as the angle about the circle's centre (deg, 0 to 360), not as the index among the angles kept."""
    phi = np.linspace(0.0, 2 * np.pi, points, endpoint=False)
    attained = np.array([in_planes(path, ev, phi) for ev in evaluations])
    every = ~np.isnan(attained).any(axis=(0, 2))
    return path_figures(path.point(phi[every]) * 1000.0, attained[:, every] * 1000.0, np.degrees(phi[every]))
