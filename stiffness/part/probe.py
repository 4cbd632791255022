"""A probe log read against the trace of the cut it probed: the touches checked, then read as a part's points
in the robot's base (docs/part.md, "The robot probes its own part").

Each touch's point p = FK_probe(q_trigger) + (r_s - v tau) d (`stiffness.part.probe_geometry`) goes through
the same reading as a CMM's point, against the same cut (`stiffness.part.rows.rows_of`), its frame the
identity: the commanded tool centre c(u) = FK(q(u)) of the trace and p are both the model's forward kinematics
of joints a fraction of a degree apart, so what the robot's geometry gets wrong, DH lengths, twists and encoder
offsets, is nearly the same in both and leaves e = |P (p - c(u))| - r to second order (the joints' difference
times the error's gradient: a few um for a 0.2 mm, 0.02 deg table error at 1 mm of deflection).

Before that, each touch is checked against the path the trace cut, in the plane across the tool axis, and a
touch that cannot be a touch of this contour is refused by line, nothing used:

* the approach direction d must point toward the wall along its normal n (from the traced tool path, the foot
  of the perpendicular on it, to the point), within MAX_APPROACH_DEG: the point is taken r_s along d, so a slant of theta misplaces it by
  r_s (1 - cos theta) along n, and a probe that moved away from the wall or along it touched something else;
* the trigger must lie where the tool passed: the point within ``near_mm`` of the tool radius off the path;
* the stylus radius must fit: when most touches lie off the wall by one common distance beyond ``near_mm``,
  the radius is named with the one that puts them on it (or the tool's diameter given as its radius), rather
  than every touch as far off; most touches off by distances that differ: the log and the trace do not belong
  together.

Before those, and where the touches as a whole are not on the wall, the likelier causes are named first: joints
outside the robot's limits, a misreading of the log that puts the touches back on the wall when undone
(`probe_suspects`), a trace that ends before the probed contour does, and touches far off the wall's height
along the tool axis (`contour.WALL_HEIGHT_MM`).

The reading is one pass down: the cut of the trace (`contour.traced_cut`), the misreadings to try
(`probe_suspects`), the log and each misreading read against the cut once (`probe_geometry.readings`), the checks
and the causes judged from those readings (`probe_checks`), then the part's rows (`rows.rows_of`).
"""

from __future__ import annotations

import numpy as np

from ..data.probe_log import ProbeLog
from ..data.trace_file import Trace
from ..kinematics.robot import Robot
from .contour import traced_cut
from .probe_checks import checked
from .probe_geometry import readings
from .probe_suspects import misreadings
from .rows import NEAR_MM, SMOOTH_HZ, PartRows, rows_of


def read_probe_against(probe: ProbeLog, trace: Trace, robot: Robot, label: str = "part",
                       near_mm: float = NEAR_MM, smooth_hz: float = SMOOTH_HZ) -> PartRows:
    """The touches of ``probe`` checked against the cut of ``trace`` (module docstring), then read as a part's
    points in the robot's base against the same cut (`rows_of`)."""
    cut = traced_cut(trace, robot)
    misread = misreadings(probe, cut)
    seen = readings(probe, misread, robot, cut, near_mm)
    part = checked(seen, misread, cut, robot, near_mm)
    rows = rows_of(part, seen[0].touches.points, seen[0].passing, cut, robot, label, np.eye(4), near_mm, smooth_hz)
    taken = (f", {probe.overtravel_mm * 1000:.1f} um of overtravel (v tau) taken back along the approach"
             if probe.overtravel_mm else "")
    rows.notes.insert(0, f"{probe.source}: {len(probe)} touches of the robot's own probe (stylus radius "
                         f"{probe.stylus_radius_mm:g} mm{taken}), read in the robot's base: no part frame")
    if probe.probing_speed_mm_s is None:
        rows.notes.insert(1, f"{probe.source}: warning: no probing_speed_mm_s and trigger_latency_ms: the probe's "
                             "travel between the contact and the latch (v tau) stays in every touch as a bias along "
                             "its normal, which learning takes for a deflection (docs/part.md: 1.08 x the exact "
                             "model's path error at 5 mm/s, 2.94 x at 50 mm/s); state both in the header")
    return rows
