"""The geometry a probe log's touches are checked by: the path the trace's tool centre cut, in the plane across
its tool axis, and each touch's offset from the wall it cut (`probe.check_touches`, `probe_suspects.explain`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from ..data.probe_log import ProbeLog
from ..data.trace_file import Trace
from ..errors import DataError
from ..kinematics.robot import Robot
from .foot import foot_on_path
from .rows import TASK_RUN, at_feed, plane_basis

MAX_APPROACH_DEG = 10.0     # a slant of 10 deg misplaces the point 1.5 % of the stylus radius along the normal
CENTRE_ON_PATH_MM = 0.5     # a stylus centre this near the tool's path: its side is told by the touched point
CHORD_STEPS = 20            # a chord between two traced samples up to this many typical steps long is the path


@dataclass
class TracedCut:
    """The path the trace's tool centre cut, in the plane across its tool axis ``a`` (axes ``e1``, ``e2``):
    ``c2`` its points there (m, time order), ``height`` the path's place along ``a`` (m) and ``q_deg`` the median
    commanded joints while it cut."""

    a: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    c2: np.ndarray
    height: float
    q_deg: np.ndarray


def traced_cut(trace: Trace, robot: Robot, what: str) -> TracedCut:
    """The cut of ``trace`` (as `read_against` reads it); DataError when nothing ran or the tool hardly moved
    (``what``: the file it should have made)."""
    run = trace.column("task_state") == TASK_RUN
    if not run.any():
        raise DataError(f"{trace.source}: no cycle of the trace ran (task state RUN): nothing was cut")
    F = robot.frames(np.radians(trace.commanded_q_deg))
    c_all = F[:, 7, :3, 3]
    moving = at_feed(trace.time_s, c_all) & run
    if moving.sum() < 3:
        raise DataError(f"{trace.source}: the tool hardly moves in this trace: it cannot have cut {what}")
    a = np.median(F[moving, 7, :3, 2], axis=0)
    a /= np.linalg.norm(a)
    e1, e2 = plane_basis(a)
    c = c_all[moving]
    return TracedCut(a, e1, e2, np.column_stack([c @ e1, c @ e2]), float(np.median(c @ a)),
                     np.median(trace.commanded_q_deg[moving], axis=0))


def wall_offsets(probe: ProbeLog, cut: TracedCut, robot: Robot
                 ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Each touch's e (mm, module docstring), the cosine of its approach with the normal toward the stylus
    centre, the side of the path the wall is on (+1: beyond the centre), and the touched point's place along the
    tool axis from the path's (mm)."""
    e1, e2 = cut.e1, cut.e2
    x = probe.centres(robot)
    dist, n = _across(cut.c2, np.column_stack([x @ e1, x @ e2]))    # across the path, toward the stylus centre
    p = probe.points(robot)
    dist_p, n_p = _across(cut.c2, np.column_stack([p @ e1, p @ e2]))
    near_path = dist < CENTRE_ON_PATH_MM / 1000.0                # a stylus about the cutter's size: its centre
    n[near_path] = n_p[near_path]                                # tells no side
    d2 = np.column_stack([probe.approach @ e1, probe.approach @ e2])
    toward = np.einsum("nk,nk->n", n, d2)
    side = 1.0 if np.median(toward) >= 0 else -1.0                # the wall beyond the centre (r_s < r) or not
    r = probe.tool_radius_mm / 1000.0
    rs = probe.stylus_radius_mm / 1000.0 - probe.overtravel_mm / 1000.0
    e_mm = (np.where(near_path, dist_p - r, side * dist - (r - rs))) * 1000.0
    return e_mm, toward, side, (p @ cut.a - cut.height) * 1000.0


def _across(c2: np.ndarray, x2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Each in-plane point's distance from the traced path (in-plane samples ``c2``, in time order) and the unit
    vector from the path to it: from the foot of the perpendicular on the chord beside the nearest sample.

    The nearest sample alone would tilt the vector by atan(s / D), s the sample's way along the path from the
    foot: a robot reporting every 4 ms at 50 mm/s, one report late, puts it 0.3 mm along at D = 2.5 mm (the
    stylus centre's distance from the tool's when r - r_s = 2.5 mm), 7 deg. A chord tilts it by half the angle
    the path turns along the chord (0.6 deg for 0.6 mm on a 17.5 mm radius). A chord longer than
    `CHORD_STEPS` typical steps is no stretch of the path (the tool left it or stood): the sample is kept."""
    _, j = cKDTree(c2).query(x2)
    steps = np.linalg.norm(np.diff(c2, axis=0), axis=1)
    longest = CHORD_STEPS * float(np.median(steps[steps > 0])) if (steps > 0).any() else 0.0
    near, foot = np.zeros(len(x2)), np.zeros_like(x2)
    for k in range(len(x2)):
        near[k], s, f = foot_on_path(c2, x2[k], int(j[k]), lambda s: 0.0 < steps[s] <= longest)
        foot[k] = c2[s] + f * (c2[s + 1] - c2[s]) if f > 0.0 else c2[s]
    return near, (x2 - foot) / np.maximum(near, 1e-12)[:, None]
