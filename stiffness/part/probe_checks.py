"""A probe log's touches judged against the wall its trace cut (`probe`'s docstring): every check of a touch,
and, where the touches as a whole are not on the wall, the misreadings of the log that put them on it, named
with their evidence, likeliest first (`explain`).

A misreading (`probe_suspects`) explains the log when, undone, it puts at least ON_SHARE of the touches within
ON_TOLERANCE of the tolerance of the wall (a third: a misreading that moves them by the stylus's diameter is not
one), at the wall's height and with their approaches along its normal (a mirror of a symmetric contour puts the
points back on it, but not the approaches); the nearest first.
"""

from __future__ import annotations

import numpy as np

from ..data.part_points import PartMeasurement
from ..errors import DataError, Problems
from ..kinematics.robot import Robot
from .contour import WALL_HEIGHT_MM, TracedCut
from .probe_geometry import Reading
from .probe_suspects import Misreading

MAX_APPROACH_DEG = 10.0     # a slant of 10 deg misplaces the point 1.5 % of the stylus radius along the normal
END_SAMPLES = 3             # a touch nearest one of the path's first or last samples lies by its end
ON_SHARE = 0.9              # a misreading that puts this share of the touches on the wall explains them,
ON_TOLERANCE = 1 / 3        # each within this share of the tolerance (a third: not a reading off by the stylus)


def checked(seen: list[Reading], misread: list[Misreading], cut: TracedCut, robot: Robot,
            near_mm: float) -> PartMeasurement:
    """The touches of the log as given (``seen[0]``; ``seen[1:]`` its ``misread`` readings) as a part measured in
    the robot's base (its frame the identity), after every check of `probe`'s docstring against ``cut``;
    DataError naming the file and every touch's line that fails one, the likeliest cause first where the touches
    as a whole are not on the wall."""
    given = seen[0]
    probe, trace, e_mm = given.touches.probe, cut.trace, given.e_mm
    likely = explain(given, list(zip(misread, seen[1:])), near_mm)
    _within_limits(given, robot, likely)
    angle = np.degrees(np.arccos(np.clip(given.side * given.toward, -1.0, 1.0)))   # |d| = 1: along the axis is 90 deg
    _trace_ends_first(given, cut, (np.abs(e_mm) > near_mm) | (angle > MAX_APPROACH_DEG))
    mid = float(np.median(e_mm))
    if (np.abs(e_mm) > near_mm).mean() > 0.5 and likely:
        raise DataError(f"{probe.source}: the touches lie a median {mid:+.2f} mm off the wall the trace "
                        f"{trace.source} cut (tolerance {near_mm:g} mm). {likely}")
    _stylus_fits(given, near_mm)
    if (np.abs(e_mm) > near_mm).mean() > 0.5:
        raise DataError(f"{probe.source}: the trace {trace.source} never passes the probed contour: the touches lie "
                        f"a median {np.median(np.abs(e_mm)):.1f} mm off the wall it cut (tolerance {near_mm:g} mm), "
                        "and not by one common distance; they do not belong together")
    height = float(np.median(given.axial_mm))
    if abs(height) > WALL_HEIGHT_MM:
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
    return PartMeasurement(probe.source, given.touches.points * 1000.0, probe.labels, probe.lines,
                           probe.tool_radius_mm, np.eye(4), probe.title, stylus_radius_mm=probe.stylus_radius_mm)


def explain(given: Reading, tried: list[tuple[Misreading, Reading]], near_mm: float) -> str:
    """'Likely causes, likeliest first: (1) ...' for the misreadings ``tried`` (each with its reading) that put
    the touches on the wall; '' when none does. Every approach reversed is a cause only where the approaches as
    given point straight back along the normal, to a wall on the near side of the stylus centre, which a stylus
    smaller than the tool cannot touch."""
    probe = given.touches.probe
    away = (given.side < 0 and float(np.median(given.toward)) < -np.cos(np.radians(MAX_APPROACH_DEG))
            and probe.stylus_radius_mm < probe.tool_radius_mm)
    found = []
    for misreading, fixed in tried:
        if misreading.reverses and not away:
            continue
        on = ((np.abs(fixed.e_mm) <= ON_TOLERANCE * near_mm) & (np.abs(fixed.axial_mm) <= WALL_HEIGHT_MM)
              & (fixed.side * fixed.toward >= np.cos(np.radians(MAX_APPROACH_DEG))))
        if on.mean() >= ON_SHARE:
            off = float(np.median(np.abs(fixed.e_mm)))
            found.append((off, (f"{misreading.text}: so read, {int(on.sum())} of {len(on)} touches lie on the wall "
                                f"({off:.2f} mm off it, median)")))
    found.sort(key=lambda f: f[0])
    if not found:
        return ""
    return "Likely causes, likeliest first: " + "; ".join(f"({k}) {t}" for k, (_, t) in enumerate(found, 1))


def _within_limits(given: Reading, robot: Robot, likely: str) -> None:
    """DataError naming every touch's line with a joint outside ``robot``'s limits (nothing used), and what
    ``likely`` says of the log (`explain`)."""
    probe, inside = given.touches.probe, given.touches.inside
    if inside.all():
        return
    problems = Problems()
    for k, j in zip(*np.nonzero(~inside)):
        lo, hi = robot.limits_deg[j]
        problems.add(f"{probe.where(k)}: q{j + 1}_deg = {probe.q_deg[k, j]:g} is outside joint {j + 1}'s limits "
                     f"[{lo:g}, {hi:g}] deg ({robot.source})")
    rad = " (in radians? the columns are degrees)" if np.abs(probe.q_deg).max() <= 2 * np.pi else ""
    raise DataError(f"{probe.source}: {int((~inside.all(axis=1)).sum())} touch(es) hold joints this robot cannot "
                    f"reach{rad}; nothing was used" + (f". {likely}" if likely else ""), problems)


def _trace_ends_first(given: Reading, cut: TracedCut, off: np.ndarray) -> None:
    """DataError when the touches that fail a check (``off``: off the wall, or approaching it slanted) lie by the
    first or last sample of the traced path (within END_SAMPLES), all but at most a fifth of them: the trace stops
    before the probed contour does (by its end, the path's normal turns and its distance grows)."""
    probe, j, e_mm = given.touches.probe, given.sample, given.e_mm
    beyond = off & ((j < END_SAMPLES) | (j >= len(cut.c2) - END_SAMPLES))
    if not off.any() or beyond.sum() < 0.8 * off.sum():
        return
    problems = Problems()
    for k in np.nonzero(beyond)[0]:
        problems.add(f"{probe.where(k)}: {e_mm[k]:+.1f} mm off the wall, beyond the traced path's "
                     f"{'first' if j[k] < END_SAMPLES else 'last'} sample")
    raise DataError(f"{probe.source}: {int(beyond.sum())} of {len(probe)} touches lie beyond where the trace "
                    f"{cut.trace.source} ends, and {int((~off).sum())} on the wall it cut: the trace stops before the "
                    "probed contour does (a recording cut short, or the trace of part of the cut); give the "
                    "whole cut's trace", problems)


def _stylus_fits(given: Reading, near_mm: float) -> None:
    """Most touches off the wall by one distance beyond ``near_mm``: the stylus radius, not the touches."""
    probe, e_mm = given.touches.probe, given.e_mm
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
