"""How much of the cut contour a part's points cover: a warning when they span less than a third of it.

A narrow stretch of the wall sees the load from few directions, so learning takes a direction it cannot see
from the prior, and the learned model cuts the rest of the contour worse. Measured in the HIL (lock step, one
run each; the too-stiff model learned from the robot's own probe of the circle, the robot with geometric
errors, the next cut against the exact model's; 2026-12-07): 10 adjacent touches spanning 26 deg of the circle
cut 1.47 x the exact model's mean path error, 30 spanning 83 deg 1.89 x, 60 spanning 169 deg 1.04 x, all 120
round it 1.02 x. Between 83 and 169 deg the cost falls away: the warning starts below 120 deg of a full turn.

The span is measured about the traced tool path's centre in the plane across the tool axis: the largest gap
between neighbouring angles, taken from the full turn, for the points and for the tool's path alike.
"""

from __future__ import annotations

import numpy as np

from .contour import plane_basis
from .rows import PartRows

SHARE_MIN = 1 / 3   # the points span at least this share of the arc the tool cut
COST = "26 deg of a circle taught a model that cut 1.47 x the exact one's path error, 83 deg 1.89 x, 169 deg 1.04 x"


def span_deg(angles_deg: np.ndarray) -> float:
    """The arc a set of angles covers: the full turn less the largest gap between neighbours (deg)."""
    a = np.sort(np.mod(angles_deg, 360.0))
    if len(a) < 2:
        return 0.0
    gaps = np.diff(np.concatenate([a, [a[0] + 360.0]]))
    return max(0.0, float(360.0 - gaps.max()))


def note(rows: PartRows) -> str | None:
    """A warning naming the part when its points span less than SHARE_MIN of the arc its trace's tool cut."""
    axis = rows.axis.mean(axis=0)
    e1, e2 = plane_basis(axis / np.linalg.norm(axis))
    centre = np.median(rows.trace_tool, axis=0)

    def angles(x: np.ndarray) -> np.ndarray:
        d = x - centre
        return np.degrees(np.arctan2(d @ e2, d @ e1))

    cut, points = span_deg(angles(rows.trace_tool)), span_deg(angles(rows.point))
    if cut <= 0 or points >= SHARE_MIN * cut:
        return None
    return (f"{rows.part.source}: warning: its {len(rows.point)} points span {points:.0f} deg of the {cut:.0f} deg "
            f"the tool cut: a narrow stretch sees the load from few directions, and what it does not see is "
            f"learned from the prior (in the HIL, {COST}); measure all round")
