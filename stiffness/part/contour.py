"""The contour's geometry: the path the tool centre took, seen along the tool axis. A trace's path is computed once
(`traced_cut`: the commanded tool centre of every row through the model's kinematics) and read by all that holds
a point against the wall the cut left: the part reader, where the tool passed abeam of each measured point
(`stiffness.part.rows`); the probe check and its suspects, each touch's distance and normal from the path
(`stiffness.part.probe_geometry`); the suspects of a CMM's units and frame (`stiffness.part.suspects`); and the
HIL's virtual probe, where its stylus meets the wall (`hil.probe`).

The path lies in the plane across the tool axis a (axes e1, e2), c2 its samples there in time order. A point's
place on it is the foot of the perpendicular on the polyline beside the point's nearest sample (`foot_on_path`).

Example: the chord from (0, 0) to (2, 0) passes abeam of (1.5, 1) at 1.5, a distance 1 from it.

>>> import numpy as np
>>> foot_on_path(np.array([[0.0, 0.0], [2.0, 0.0], [2.0, 2.0]]), np.array([1.5, 1.0]), 0)
(1.0, 0, 0.75)
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
from scipy.spatial import cKDTree

from ..data.trace_file import Gap, Trace
from ..errors import DataError
from ..kinematics.robot import Robot
from .left_out import GAP_MARGIN_MM, Jump, jumps

TASK_RUN = 1
CHORD_STEPS = 20         # a chord between two traced samples up to this many typical steps long is the path
PASS_MARGIN_MM = 0.5     # another pass made a point too when it came this close to the closest pass's distance
WALL_HEIGHT_MM = 50.0    # a measured wall lies within this of the tool centre's path along the tool axis (an end
                         # mill's flutes reach a few diameters; 250 mm is a frame in metres)


@dataclass
class ToolPath:
    """A tool centre's path seen along its tool axis: its samples ``c`` (m, time order) and the unit axis ``a``;
    ``e1``, ``e2`` span the plane across a, and ``c2`` holds the samples there."""

    c: np.ndarray
    a: np.ndarray
    e1: np.ndarray = field(init=False)
    e2: np.ndarray = field(init=False)
    c2: np.ndarray = field(init=False)

    def __post_init__(self) -> None:
        self.e1, self.e2 = plane_basis(self.a)
        self.c2 = self.in_plane(self.c)

    @cached_property
    def height(self) -> float:
        """The path's place along the tool axis (m, median)."""
        return float(np.median(self.c @ self.a))

    @cached_property
    def tree(self) -> cKDTree:
        """The samples' search tree in the plane."""
        return cKDTree(self.c2)

    @cached_property
    def steps(self) -> np.ndarray:
        """The length of each chord between two samples in the plane (m)."""
        return np.linalg.norm(np.diff(self.c2, axis=0), axis=1)

    def in_plane(self, x: np.ndarray) -> np.ndarray:
        """Points (n, 3) in the plane's axes (n, 2)."""
        return np.column_stack([x @ self.e1, x @ self.e2])

    def feet(self, x2: np.ndarray, chord_steps: float = CHORD_STEPS) -> tuple[np.ndarray, np.ndarray]:
        """Each in-plane point's distance from the path and the foot of its perpendicular on the chord beside
        its nearest sample.

        The nearest sample alone would tilt the direction to the point by atan(s / D), s the sample's way along
        the path from the foot: a robot reporting every 4 ms at 50 mm/s, one report late, puts it 0.3 mm along at
        D = 2.5 mm (a stylus centre's distance from the tool's when r - r_s = 2.5 mm), 7 deg. A chord tilts it by
        half the angle the path turns along the chord (0.6 deg for 0.6 mm on a 17.5 mm radius). A chord longer
        than ``chord_steps`` typical steps is no stretch of the path (the tool left it or stood): the sample is
        kept (``np.inf``: every chord is the path)."""
        _, j = self.tree.query(x2)
        steps = self.steps
        longest = chord_steps * float(np.median(steps[steps > 0])) if (steps > 0).any() else 0.0
        near, foot = np.zeros(len(x2)), np.zeros_like(x2)
        for k in range(len(x2)):
            near[k], s, f = foot_on_path(self.c2, x2[k], int(j[k]), lambda s: 0.0 < steps[s] <= longest)
            foot[k] = self.c2[s] + f * (self.c2[s + 1] - self.c2[s]) if f > 0.0 else self.c2[s]
        return near, foot

    def across(self, x2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each in-plane point's distance from the path and the unit vector from the path to it (`feet`)."""
        near, foot = self.feet(x2)
        return near, (x2 - foot) / np.maximum(near, 1e-12)[:, None]


@dataclass
class TracedCut(ToolPath):
    """The path a trace's tool centre cut, seen along its tool axis: ``c`` the commanded tool centre of the trace's
    ``rows`` where it moved at the feed, ``tool`` of every row of ``trace`` (m), ``run`` the rows whose task ran, and
    ``q_deg`` the median commanded joints while it cut."""

    trace: Trace
    tool: np.ndarray
    run: np.ndarray
    rows: np.ndarray
    q_deg: np.ndarray

    @cached_property
    def blind(self) -> list[Gap | Jump]:
        """Where the trace is blind, in row order: the rows it lost (`Trace.gaps`) and where its joints jumped
        (`left_out.jumps`)."""
        return sorted(self.trace.gaps() + jumps(self.trace, self.tool, self.run), key=lambda b: b.row)

    def passing(self, p2: np.ndarray, r: float, near_m: float) -> Passing:
        """Where the path passes the in-plane points ``p2``: each one's nearest sample, and, for each one on the
        wall (the tool radius ``r`` off the path within ``near_m``, m), how many passes of the tool came within
        PASS_MARGIN_MM as close as the closest one and, where one did, the fractional trace row abeam of it and
        the blind span (`blind`) the path passed within GAP_MARGIN_MM of there."""
        near, j = self.tree.query(p2)
        passes, u = np.zeros(len(p2), dtype=int), np.full(len(p2), np.nan)
        for k in np.nonzero(np.abs(near - r) <= near_m)[0]:
            cand = np.sort(np.array(self.tree.query_ball_point(p2[k], near[k] + PASS_MARGIN_MM / 1000.0), dtype=int))
            passes[k] = 1 + int(np.sum(np.diff(cand) > 1)) if len(cand) else 0
            if passes[k] == 1:
                u[k] = self._abeam(p2[k], cand)
        return Passing(near, self.rows[j], passes, u, self._blind_near(u))

    def _blind_near(self, u: np.ndarray) -> np.ndarray:
        """For each fractional trace row ``u``, the index into `blind` of the span the path passed within
        GAP_MARGIN_MM of there, or -1 (also for NaN): by the path's length, so a tool standing still adds nothing."""
        s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(self.tool, axis=0), axis=1))])
        s_u = np.interp(u, np.arange(len(s)), s)
        out, margin = np.full(len(u), -1), GAP_MARGIN_MM / 1000.0
        for g, b in enumerate(self.blind):
            out[(s_u >= s[b.row] - margin) & (s_u <= s[b.row + 1] + margin) & (out < 0)] = g
        return out

    def _abeam(self, p2: np.ndarray, near: np.ndarray) -> float:
        """The fractional trace row where the path passes abeam of the in-plane point ``p2``: the foot of the
        perpendicular on the polyline beside the nearest of its samples ``near`` (chords between rows that follow
        each other)."""
        j = int(near[np.argmin(np.linalg.norm(self.c2[near] - p2, axis=1))])
        _, s, f = foot_on_path(self.c2, p2, j, lambda s: self.rows[s + 1] == self.rows[s] + 1)
        return float(self.rows[s] + f)


@dataclass
class Passing:
    """Where a cut's path passes some points (`TracedCut.passing`): ``near`` each one's distance from its nearest
    sample (m) and ``row`` that sample's trace row; ``passes`` how many passes of the tool came about as close (0
    for a point off the wall), ``u`` the fractional trace row abeam of it where one pass did (NaN elsewhere), and
    ``blind`` the index of the blind span of the trace (`TracedCut.blind`) the path passed near there (-1: none).
    Separate passes are runs of moving samples that do not follow each other (a stalled host leaves no such gap)."""

    near: np.ndarray
    row: np.ndarray
    passes: np.ndarray
    u: np.ndarray
    blind: np.ndarray


def traced_cut(trace: Trace, robot: Robot) -> TracedCut:
    """The cut of ``trace`` through ``robot``'s kinematics; DataError naming the trace when nothing ran or the tool
    hardly moved."""
    run = trace.column("task_state") == TASK_RUN
    if not run.any():
        raise DataError(f"{trace.source}: no cycle of the trace ran (task state RUN): nothing was cut")
    q_deg = trace.commanded_q_deg
    F = robot.frames(np.radians(q_deg))
    tool = F[:, 7, :3, 3]
    moving = at_feed(trace.time_s, tool) & run
    if moving.sum() < 3:
        raise DataError(f"{trace.source}: the tool hardly moves in this trace: it cannot have cut a part")
    a = np.median(F[moving, 7, :3, 2], axis=0)
    a /= np.linalg.norm(a)
    return TracedCut(tool[moving], a, trace=trace, tool=tool, run=run, rows=np.nonzero(moving)[0],
                     q_deg=np.median(q_deg[moving], axis=0))


def at_feed(t: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Samples where the tool moves at a cutting feed: faster than a quarter of its typical speed."""
    v = np.zeros(len(t))
    dt = np.diff(t)
    step = np.linalg.norm(np.diff(c, axis=0), axis=1)
    v[1:] = np.where(dt > 0, step / np.where(dt > 0, dt, 1.0), 0.0)
    fast = v[v > 1e-6]
    if not len(fast):
        return np.zeros(len(t), dtype=bool)
    return v > 0.25 * np.percentile(fast, 90)


def plane_basis(a: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane across ``a``."""
    h = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = h - (h @ a) * a
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(a, e1)


def foot_on_path(c2: np.ndarray, p: np.ndarray, j: int, chord=lambda s: True) -> tuple[float, int, float]:
    """The foot of the perpendicular from ``p`` on the polyline ``c2`` (samples in time order) beside its
    sample ``j``, on the chords s -> s + 1 (s = j - 1, j) that ``chord(s)`` takes for the path: its distance
    from p, the chord s and the fraction along it; the sample j itself (fraction 0) where none is nearer."""
    best = (float(np.linalg.norm(c2[j] - p)), j, 0.0)
    for s in (j - 1, j):
        if s < 0 or s + 1 >= len(c2) or not chord(s):
            continue
        seg = c2[s + 1] - c2[s]
        L2 = float(seg @ seg)
        f = 0.0 if L2 == 0 else float(np.clip((p - c2[s]) @ seg / L2, 0.0, 1.0))
        dist = float(np.linalg.norm(c2[s] + f * seg - p))
        if dist < best[0]:
            best = (dist, s, f)
    return best
