"""Why a probe log's touches do not lie on the wall its trace cut, when they do not: each plausible misreading
of the log tried, and those that put the touches on the wall named with their evidence, likeliest first
(as `suspects` does for a CMM's radius and frame).

Each misreading is undone on a copy of the log and its touches measured again against the cut
(`probe_geometry.wall_offsets`): it explains the log when it puts at least ON_SHARE of the touches within the
tolerance of the wall (a third of it: a misreading that moves them by the stylus's diameter is not one), at the
wall's height and with their approaches along its normal (a mirror of a symmetric contour puts the points back
on it, but not the approaches); the nearest first. The misreadings tried:

* joints in radians (every |q| below 2 pi, read as degrees);
* one joint's sign flipped, or one joint offset from the cut's (by the difference of the medians of the
  touches' and the cut's joints rounded to OFFSET_DEG, when that is over OFFSET_DEG: a joint zero of another
  convention is a round angle, and the touches' joints differ from the cut's medians by a little);
* a probe_frame in metres, or its length along another axis of the flange (the flange's frame for the stylus's);
* every approach reversed.

A stylus radius that is off is not among them: `probe._stylus_fits` names it from the touches' common distance.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace

import numpy as np

from ..data.probe_log import ProbeLog
from ..errors import DataError, Problems
from ..kinematics.robot import PoseConfig, Robot
from .contour import WALL_HEIGHT_MM, TracedCut
from .probe_geometry import MAX_APPROACH_DEG, Touches, touches_in_base, wall_offsets

ON_SHARE = 0.9       # a misreading that puts this share of the touches on the wall explains them,
ON_TOLERANCE = 1 / 3   # each within this share of the tolerance (a third: not a reading off by the stylus)
OFFSET_DEG = 5.0     # a joint whose touches sit this far from the cut's (median) is tried shifted back


def outside_limits(probe: ProbeLog, robot: Robot, likely: Callable[[], str]) -> None:
    """DataError naming every touch's line with a joint outside the robot's limits (nothing used), and what
    ``likely()`` says of the log (`explain`)."""
    inside = robot.within_limits(probe.q_deg)
    if inside.all():
        return
    problems = Problems()
    for k, j in zip(*np.nonzero(~inside)):
        lo, hi = robot.limits_deg[j]
        problems.add(f"{probe.where(k)}: q{j + 1}_deg = {probe.q_deg[k, j]:g} is outside joint {j + 1}'s limits "
                     f"[{lo:g}, {hi:g}] deg ({robot.source})")
    rad = " (in radians? the columns are degrees)" if np.abs(probe.q_deg).max() <= 2 * np.pi else ""
    why = likely()
    raise DataError(f"{probe.source}: {int((~inside.all(axis=1)).sum())} touch(es) hold joints this robot cannot "
                    f"reach{rad}; nothing was used" + (f". {why}" if why else ""), problems)


def explain(touches: Touches, cut: TracedCut, robot: Robot, near_mm: float) -> str:
    """'Likely causes, likeliest first: (1) ...' for the misreadings of the log that put its ``touches`` on the
    wall of ``cut`` (each misreading undone, through ``robot``'s kinematics); '' when none does."""
    probe = touches.probe
    found = []
    _, toward, side, _ = wall_offsets(touches, cut)
    away = side < 0 and float(np.median(toward)) < -np.cos(np.radians(MAX_APPROACH_DEG))
    for text, fixed in _misreadings(probe, cut, reversed_may=away and probe.stylus_radius_mm < probe.tool_radius_mm):
        e_mm, toward_fixed, side_fixed, axial_mm = wall_offsets(touches_in_base(fixed, robot), cut)
        on = ((np.abs(e_mm) <= ON_TOLERANCE * near_mm) & (np.abs(axial_mm) <= WALL_HEIGHT_MM)
              & (side_fixed * toward_fixed >= np.cos(np.radians(MAX_APPROACH_DEG))))
        if on.mean() >= ON_SHARE:
            off = float(np.median(np.abs(e_mm)))
            found.append((off, (f"{text}: so read, {int(on.sum())} of {len(on)} touches lie on the wall ({off:.2f} mm "
                               "off it, median)")))
    found.sort(key=lambda f: f[0])
    if not found:
        return ""
    return "Likely causes, likeliest first: " + "; ".join(f"({k}) {t}" for k, (_, t) in enumerate(found, 1))


def _misreadings(probe: ProbeLog, cut: TracedCut, reversed_may: bool):
    """(words, the log with the misreading undone) for each misreading of the module's docstring; the approach
    reversed only where ``reversed_may``: the approaches point straight back along the normal, to a wall on the
    near side of the stylus centre, which a stylus smaller than the tool cannot touch."""
    q = probe.q_deg
    if np.abs(q).max() <= 2 * np.pi:
        yield "the joints are in radians (the columns are q1_deg .. q6_deg, degrees)", replace(probe, q_deg=np.degrees(q))
    for j in range(6):
        if np.abs(q[:, j]).max() > 0:
            flipped = q.copy()
            flipped[:, j] *= -1.0
            yield f"q{j + 1}_deg has the wrong sign", replace(probe, q_deg=flipped)
        off = float(cut.q_deg[j] - np.median(q[:, j]))
        off = float(np.round(off / OFFSET_DEG) * OFFSET_DEG)     # a convention's zero is a round angle (90, 180)
        if abs(off) > OFFSET_DEG:
            shifted = q.copy()
            shifted[:, j] += off
            yield (f"q{j + 1}_deg is {-off:+.1f} deg off the cut's joint {j + 1} (a zero of another convention?)",
                   replace(probe, q_deg=shifted))
    xyz = np.array(probe.probe_frame.xyz_mm, dtype=float)
    length = float(np.linalg.norm(xyz))
    rpy = list(probe.probe_frame.rpy_deg)
    if 0 < length < 5.0:
        yield (f"probe_frame's xyz_mm {_v(xyz)} is in metres: {_v(1000 * xyz)} mm",
               replace(probe, probe_frame=PoseConfig(xyz_mm=list(1000 * xyz), rpy_deg=rpy)))
    for axis in range(3):
        for sign in (1.0, -1.0):
            along = np.zeros(3)
            along[axis] = sign * length
            if length > 0 and not np.allclose(along, xyz):
                yield ((f"probe_frame's xyz_mm {_v(xyz)} puts the stylus off the flange's {'xyz'[axis]} axis: "
                       f"{_v(along)} (the stylus centre in the flange frame, DH frame 6)"),
                       replace(probe, probe_frame=PoseConfig(xyz_mm=list(along), rpy_deg=rpy)))
    if reversed_may:
        yield ("every approach is reversed (it points from the wall to the stylus)",
               replace(probe, approach=-probe.approach))


def _v(x: np.ndarray) -> str:
    return "[" + ", ".join(f"{v:g}" for v in x) + "]"
