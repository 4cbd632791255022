"""A probe log's touches in the robot's base, and each touch's offset from the wall its trace cut
(`probe.check_touches`, `probe_suspects.explain`).

The touched point, through the model's own (nominal) kinematics, is the stylus ball's centre at the trigger plus
the stylus radius, less the probe's travel between the contact and the latch, along the approach:

    p = FK_probe(q_trigger) + (r_s - v tau) d        d the approach direction, r_s the stylus radius

The cut's commanded tool centre is FK(q_commanded + correction) through the same kinematics (`contour.traced_cut`),
at nearly the same joints, so the robot's geometric errors cancel to first order between the two.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..data.part_points import PartMeasurement
from ..data.probe_log import ProbeLog
from ..kinematics.robot import Robot
from .contour import ToolPath

MAX_APPROACH_DEG = 10.0     # a slant of 10 deg misplaces the point 1.5 % of the stylus radius along the normal
CENTRE_ON_PATH_MM = 0.5     # a stylus centre this near the tool's path: its side is told by the touched point


@dataclass
class Touches:
    """The touches of ``probe`` in the robot's base (N, 3, m): the stylus ball's centre at each trigger, and the
    touched point."""

    probe: ProbeLog
    centres: np.ndarray
    points: np.ndarray

    def as_part(self) -> PartMeasurement:
        """The touched points as a part measured in the robot's base (its frame the identity)."""
        log = self.probe
        return PartMeasurement(log.source, self.points * 1000.0, log.labels, log.lines, log.tool_radius_mm,
                               np.eye(4), log.title, stylus_radius_mm=log.stylus_radius_mm)


def touches_in_base(probe: ProbeLog, robot: Robot) -> Touches:
    """Where ``probe``'s touches were, through ``robot``'s kinematics: each centre plus the stylus radius, less
    the overtravel, along the approach."""
    F = robot.frames(np.radians(probe.q_deg))
    centres = (F[:, 6] @ probe.probe_frame.matrix())[:, :3, 3]
    reach = (probe.stylus_radius_mm - probe.overtravel_mm) / 1000.0
    return Touches(probe, centres, centres + reach * probe.approach)


def wall_offsets(touches: Touches, cut: ToolPath) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """Each touch's e (mm, `probe`'s docstring), the cosine of its approach with the normal toward the stylus
    centre, the side of the path the wall is on (+1: beyond the centre), and the touched point's place along the
    tool axis from the path's (mm)."""
    probe = touches.probe
    dist, n = cut.across(cut.in_plane(touches.centres))     # across the path, toward the stylus centre
    dist_p, n_p = cut.across(cut.in_plane(touches.points))
    near_path = dist < CENTRE_ON_PATH_MM / 1000.0                # a stylus about the cutter's size: its centre
    n[near_path] = n_p[near_path]                                # tells no side
    toward = np.einsum("nk,nk->n", n, cut.in_plane(probe.approach))
    side = 1.0 if np.median(toward) >= 0 else -1.0                # the wall beyond the centre (r_s < r) or not
    r = probe.tool_radius_mm / 1000.0
    rs = probe.stylus_radius_mm / 1000.0 - probe.overtravel_mm / 1000.0
    e_mm = (np.where(near_path, dist_p - r, side * dist - (r - rs))) * 1000.0
    return e_mm, toward, side, (touches.points @ cut.a - cut.height) * 1000.0
