"""A probe log read against the cut its trace made: its touches in the robot's base, and each touch's offset
from the wall the cut left, for the log as given and for each of its misreadings undone (`readings`), computed
once and judged by `probe_checks`.

The touched point, through the model's own (nominal) kinematics, is the stylus ball's centre at the trigger plus
the stylus radius, less the probe's travel between the contact and the latch, along the approach:

    p = FK_probe(q_trigger) + (r_s - v tau) d        d the approach direction, r_s the stylus radius

The cut's commanded tool centre is FK(q_commanded + correction) through the same kinematics (`contour.traced_cut`),
at nearly the same joints, so the robot's geometric errors cancel to first order between the two.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.probe_log import ProbeLog
from ..kinematics.robot import Robot
from .contour import Passing, TracedCut
from .probe_suspects import Misreading

CENTRE_ON_PATH_MM = 0.5     # a stylus centre this near the tool's path: its side is told by the touched point


@dataclass
class Touches:
    """The touches of ``probe`` in the robot's base (N, 3, m): the stylus ball's centre at each trigger, and the
    touched point; ``inside`` (N, 6) which of their joints lie within the robot's limits."""

    probe: ProbeLog
    centres: np.ndarray
    points: np.ndarray
    inside: np.ndarray


@dataclass
class Reading:
    """A reading of a probe log against a cut: its ``touches``, each one's e (mm, `probe`'s docstring), the
    cosine of its approach with the normal toward the stylus centre (``toward``), the side of the path the wall
    is on (+1: beyond the centre), the touched point's place along the tool axis from the path's (mm), and the
    path's sample nearest each stylus centre. ``passing``: where the path passes each touched point
    (`TracedCut.passing`), for the log as given."""

    touches: Touches
    e_mm: np.ndarray
    toward: np.ndarray
    side: float
    axial_mm: np.ndarray
    sample: np.ndarray
    passing: Passing | None = None


def touches_in_base(probe: ProbeLog, robot: Robot) -> Touches:
    """Where ``probe``'s touches were, through ``robot``'s kinematics: each centre plus the stylus radius, less
    the overtravel, along the approach."""
    inside = robot.within_limits(probe.q_deg)
    F = robot.frames(np.radians(probe.q_deg))
    centres = (F[:, 6] @ probe.probe_frame.matrix())[:, :3, 3]
    reach = (probe.stylus_radius_mm - probe.overtravel_mm) / 1000.0
    return Touches(probe, centres, centres + reach * probe.approach, inside)


def readings(probe: ProbeLog, misread: list[Misreading], robot: Robot, cut: TracedCut,
             near_mm: float) -> list[Reading]:
    """``probe`` read against ``cut`` through ``robot``'s kinematics, then each of its misreadings undone: the log
    as given first, and where its touched points pass the path (on the wall within ``near_mm``) for it alone."""
    seen = []
    for k, log in enumerate([probe, *(m.log for m in misread)]):
        seen.append(_reading(log, robot, cut, near_mm if k == 0 else None))
    return seen


def _reading(probe: ProbeLog, robot: Robot, cut: TracedCut, near_mm: float | None) -> Reading:
    """One log read against ``cut`` (`Reading`'s fields); ``near_mm`` None: without where the path passes."""
    touches = touches_in_base(probe, robot)
    r = probe.tool_radius_mm / 1000.0
    centres, points = cut.in_plane(touches.centres), cut.in_plane(touches.points)
    dist, n = cut.across(centres)                                # across the path, toward the stylus centre
    dist_p, n_p = cut.across(points)
    _, sample = cut.tree.query(centres)
    passing = None if near_mm is None else cut.passing(points, r, near_mm / 1000.0)
    near_path = dist < CENTRE_ON_PATH_MM / 1000.0                # a stylus about the cutter's size: its centre
    n[near_path] = n_p[near_path]                                # tells no side
    toward = np.einsum("nk,nk->n", n, cut.in_plane(probe.approach))
    side = 1.0 if np.median(toward) >= 0 else -1.0                # the wall beyond the centre (r_s < r) or not
    rs = probe.stylus_radius_mm / 1000.0 - probe.overtravel_mm / 1000.0
    e_mm = (np.where(near_path, dist_p - r, side * dist - (r - rs))) * 1000.0
    return Reading(touches, e_mm, toward, side, (touches.points @ cut.a - cut.height) * 1000.0, sample, passing)
