"""A probe log read against the trace of the cut it probed: the touches checked, then read as a part's points
in the robot's base (docs/part.md, "The robot probes its own part").

Each touch's point p = FK_probe(q_trigger) + (r_s - v tau) d (`stiffness.part.probe_geometry`) goes through
the same reading as a CMM's point, against the same cut (`stiffness.part.rows.read_cut`), its frame the
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
"""

from __future__ import annotations

import numpy as np

from ..data.probe_log import ProbeLog
from ..data.trace_file import Trace
from ..errors import DataError, Problems
from ..kinematics.robot import Robot
from .contour import WALL_HEIGHT_MM, TracedCut, traced_cut
from .probe_geometry import MAX_APPROACH_DEG, Touches, touches_in_base, wall_offsets
from .probe_suspects import explain, outside_limits
from .rows import NEAR_MM, SMOOTH_HZ, PartRows, read_cut

END_SAMPLES = 3             # a touch nearest one of the path's first or last samples lies by its end


def read_probe_against(probe: ProbeLog, trace: Trace, robot: Robot, label: str = "part",
                       near_mm: float = NEAR_MM, smooth_hz: float = SMOOTH_HZ) -> PartRows:
    """The touches of ``probe`` checked against the cut of ``trace`` (module docstring), then read as a part's
    points in the robot's base against the same cut (`read_cut`)."""
    cut = traced_cut(trace, robot, probe.source)
    touches = check_touches(probe, cut, robot, near_mm)
    rows = read_cut(touches.as_part(), cut, robot, label, near_mm=near_mm, smooth_hz=smooth_hz)
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


def check_touches(probe: ProbeLog, cut: TracedCut, robot: Robot, near_mm: float = NEAR_MM) -> Touches:
    """The touches of ``probe`` in the robot's base, after the checks of the module's docstring against ``cut``;
    DataError naming the file and every touch's line that fails one, the likeliest cause first (`probe_suspects`)
    where the touches as a whole are not on the wall."""
    trace = cut.trace
    touches = touches_in_base(probe, robot)
    outside_limits(probe, robot, lambda: explain(touches, cut, robot, near_mm))
    e_mm, toward, side, axial_mm = wall_offsets(touches, cut)
    angle = np.degrees(np.arccos(np.clip(side * toward, -1.0, 1.0)))    # |d| = 1: along the tool axis is 90 deg
    _trace_ends_first(touches, cut, e_mm, (np.abs(e_mm) > near_mm) | (angle > MAX_APPROACH_DEG))
    mid = float(np.median(e_mm))
    if (np.abs(e_mm) > near_mm).mean() > 0.5:
        likely = explain(touches, cut, robot, near_mm)
        if likely:
            raise DataError(f"{probe.source}: the touches lie a median {mid:+.2f} mm off the wall the trace "
                            f"{trace.source} cut (tolerance {near_mm:g} mm). {likely}")
    _stylus_fits(probe, e_mm, near_mm)
    if (np.abs(e_mm) > near_mm).mean() > 0.5:
        raise DataError(f"{probe.source}: the trace {trace.source} never passes the probed contour: the touches lie "
                        f"a median {np.median(np.abs(e_mm)):.1f} mm off the wall it cut (tolerance {near_mm:g} mm), "
                        "and not by one common distance; they do not belong together")
    height = float(np.median(axial_mm))
    if abs(height) > WALL_HEIGHT_MM:
        likely = explain(touches, cut, robot, near_mm)
        raise DataError(f"{probe.source}: the touches lie {height:+.1f} mm along the tool axis from the tool centre's "
                        f"path (median), where a wall the tool cut is within {WALL_HEIGHT_MM:g} mm of it. "
                        + (likely or "Likely probe_frame's xyz_mm: the stylus centre in the flange frame, in mm"))
    problems = Problems()
    for k in range(len(probe)):
        d = probe.approach[k]
        if angle[k] > MAX_APPROACH_DEG:
            problems.add(f"{probe.where(k)}: the approach ({d[0]:+.3f}, {d[1]:+.3f}, {d[2]:+.3f}) is not toward "
                         f"the contour: it makes {angle[k]:.0f} deg with the wall's normal there (at most "
                         f"{MAX_APPROACH_DEG:g} deg: the probe moves toward the wall along its normal)")
        elif abs(e_mm[k]) > near_mm:
            problems.add(f"{probe.where(k)}: the trigger lies {e_mm[k]:+.2f} mm off the wall the trace "
                         f"{trace.source} cut (tolerance {near_mm:g} mm): far from any point the tool traced, the "
                         "probe touched something else")
    if problems:
        raise DataError(f"{probe.source}: {problems.count} touch(es) are not touches of the contour the trace "
                        "cut; nothing was used", problems)
    return touches


def _trace_ends_first(touches: Touches, cut: TracedCut, e_mm: np.ndarray, off: np.ndarray) -> None:
    """DataError when the touches that fail a check (``off``: off the wall, or approaching it slanted) lie by the
    first or last sample of the traced path (within END_SAMPLES), all but at most a fifth of them: the trace stops
    before the probed contour does (by its end, the path's normal turns and its distance grows)."""
    probe, trace = touches.probe, cut.trace
    _, j = cut.tree.query(cut.in_plane(touches.centres))
    beyond = off & ((j < END_SAMPLES) | (j >= len(cut.c2) - END_SAMPLES))
    if not off.any() or beyond.sum() < 0.8 * off.sum():
        return
    problems = Problems()
    for k in np.nonzero(beyond)[0]:
        problems.add(f"{probe.where(k)}: {e_mm[k]:+.1f} mm off the wall, beyond the traced path's "
                     f"{'first' if j[k] < END_SAMPLES else 'last'} sample")
    raise DataError(f"{probe.source}: {int(beyond.sum())} of {len(probe)} touches lie beyond where the trace "
                    f"{trace.source} ends, and {int((~off).sum())} on the wall it cut: the trace stops before the "
                    "probed contour does (a recording cut short, or the trace of part of the cut); give the "
                    "whole cut's trace", problems)


def _stylus_fits(probe: ProbeLog, e_mm: np.ndarray, near_mm: float) -> None:
    """Most touches off the wall by one distance beyond ``near_mm``: the stylus radius, not the touches."""
    mid = float(np.median(e_mm))
    common = np.abs(e_mm - mid) <= near_mm
    if abs(mid) > near_mm and common.mean() > 0.5:
        fit, r = probe.stylus_radius_mm - mid, probe.tool_radius_mm
        if abs(r + mid - r / 2) <= near_mm / 2:           # e = dist - (r - r_s): a tool radius r too large by D is -D
            raise DataError(f"{probe.source}: tool_radius_mm = {r:g} is the cutter's diameter? {int(common.sum())} of "
                            f"{len(e_mm)} touches lie {mid:+.2f} mm off the wall the trace cut (median), and a tool "
                            f"radius of {r / 2:g} mm puts them on it, within the arm's deflection")
        better = (f"a stylus radius of about {fit:.1f} mm (or a tool radius of about {r + mid:.1f} mm) would put them "
                  "on it, within the arm's deflection" if fit > 0 else
                  "no stylus radius puts them on it: is tool_radius_mm the cutter's?")
        raise DataError(f"{probe.source}: stylus_radius_mm = {probe.stylus_radius_mm:g} does not fit: "
                        f"{int(common.sum())} of {len(e_mm)} touches lie {mid:+.2f} mm off the wall the trace cut "
                        f"(median), {better}; give the stylus's effective radius (from a ring gauge)")
