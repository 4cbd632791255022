"""Why a part's points do not lie where its trace's tool passed: every plausible cause, each with its evidence.

Three causes put the measured contour off the tool centre's path offset by the tool radius r, and each leaves
its own mark on the distances d_k from the path to the points k (in the plane of the cut):

* a wrong tool radius: every point the same distance off, d_k ≈ d for all k, and d the true radius. A radius
  given as the diameter is 2 d; one in inches (a QIF part in inches, its radius typed as it reads) is d / 25.4;
* a part_frame that is off: a shift or a turn of the part moves it nearer the path on one side than on the
  other, so d_k varies round the contour; a best fit of the frame (`fit`) then puts every point on it;
* a file of another cut: the contour is not this path's at all. With a constant d it cannot be told from a
  wrong radius by the points alone; its size against the path's is the evidence.

`explain` returns the refusal's text, the likeliest cause first.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from ..data.part_points import PartMeasurement
from ..errors import DataError
from .contour import ToolPath, TracedCut

INCH_MM = 25.4
UNITS = {"inches": INCH_MM, "metres": 1000.0}
ON_SHARE = 0.9           # a radius that puts this share of the points on the contour explains them


def radius_key(part: PartMeasurement) -> str:
    """Where the tool radius of ``part`` was given: --tool-radius-mm for a QIF part, else the file's key."""
    return "--tool-radius-mm" if str(part.source).lower().endswith(".qif") else "tool_radius_mm"


def placing_keys(part: PartMeasurement) -> tuple[str, str]:
    """The two keys that place ``part``'s points on the wall: the radius that puts each point off along its normal
    and the frame that puts them all in the robot's base. A probe log's touches are placed by the stylus ball
    (``stylus_radius_mm``, ``probe_frame``: `stiffness.data.probe_log`), a CMM's points by the tool and the
    part's frame."""
    if part.probed:
        return "stylus_radius_mm or tool_radius_mm", "probe_frame"
    return radius_key(part), "part_frame"


def explain(part: PartMeasurement, trace_source, near_m: np.ndarray, path_span_mm: float,
            fit: Callable[[], tuple[float, float, float]] | None, near_mm: float) -> str:
    """The refusal of a part whose points mostly lie off the path the trace's tool centre took.

    Parameters
    ----------
    part : PartMeasurement
        The part (its ``tool_radius_mm``, mm).
    trace_source
        The trace's file, for the message.
    near_m : ndarray
        Each point's distance from the tool centre's path in the plane of the cut, m.
    path_span_mm : float
        The largest extent of the tool's path plus the tool (2 r), in the plane, mm.
    fit : callable, optional
        A best fit of the part frame: returns (shift mm, turn deg, the points' median distance from the contour
        after it, mm); None where the part has no frame to fit.
    near_mm : float
        How far from the tool radius off the path a point may lie and still be on the contour (the largest
        deflection expected), mm: the points' distances spread by less than this are "one distance", which
        the arm's deflection varies but a frame that is off would spread by more.
    """
    r = part.tool_radius_mm
    d = 1000.0 * near_m
    med, lo, hi = float(np.median(d)), float(np.percentile(d, 5)), float(np.percentile(d, 95))
    return (f"{part.source}: the trace {trace_source} never passes the measured contour: the points lie {med:.2f} "
            f"mm from the tool centre's path (median; 90 % within {lo:.2f} to {hi:.2f} mm), where "
            f"{radius_key(part)} = {r:g} mm puts them {r:g} mm from it. "
            + causes(part, near_m, path_span_mm, fit, near_mm))


def causes(part: PartMeasurement, near_m: np.ndarray, path_span_mm: float,
           fit: Callable[[], tuple[float, float, float]] | None, near_mm: float) -> str:
    """"Likely causes, likeliest first: (1) ...; (2) ...": the causes of points off the path, each with its
    evidence (the parameters as `explain`'s)."""
    r = part.tool_radius_mm
    d = 1000.0 * near_m
    med, lo, hi = float(np.median(d)), float(np.percentile(d, 5)), float(np.percentile(d, 95))
    key = f"{radius_key(part)} = {r:g} mm"
    span = float(np.max(np.ptp(part.points_mm, axis=0)))
    size = f"the contour spans {span:.1f} mm, the tool's path with the tool {path_span_mm:.1f} mm"
    if hi - lo < near_mm:
        radius = (f"the tool radius: every point lies {med:.2f} mm from the path, within {hi - lo:.2f} mm of one "
                  f"another, as a tool of radius {med:.2f} mm leaves them; {key} is {r / med:.3g} x that"
                  + _radius_words(r, d, near_mm))
        other = (f"a file of another cut, whose contour lies {med - r:+.2f} mm off this one all round, if the "
                 f"radius is right ({size})")
        frame = ("the part_frame: unlikely, a frame that is off puts the points nearer the path on one side than "
                 f"on the other, and these lie within {hi - lo:.2f} mm of one distance")
        found = [radius, other, frame]
    else:
        found = []
        if fit is not None:
            shift, turn, left = fit()
            fits = left < near_mm / 2
            found.append(f"the part_frame{'' if fits else ' (no fit found)'}: a best fit moves it {shift:.2f} mm and "
                         f"turns it {turn:.2f} deg, and then the points lie {left:.2f} mm (median) from the contour"
                         + ("" if fits else "; a frame alone does not explain them"))
        found.append(f"a file of another cut: {size}")
        found.append("the tool radius: unlikely alone, a wrong radius puts every point the same distance off, and "
                     f"these lie {lo:.2f} to {hi:.2f} mm from the path")
    return "Likely causes, likeliest first: " + "; ".join(f"({k}) {c}" for k, c in enumerate(found, 1))


def frame_fit(part: PartMeasurement, T: np.ndarray, cut: ToolPath, r: float) -> tuple[float, float, float]:
    """The evidence for a part_frame that is off: how far the best fit ``T`` (base <- part, m) moves the part's own
    frame (mm) and turns it (deg), and the points' median distance from the contour after it (mm). ``cut``: the
    tool centre's path; ``r``: the tool radius (m)."""
    near, _ = cut.tree.query(cut.in_plane(part.in_base(T)))
    turn = np.degrees(np.arccos(np.clip((np.trace(T[:3, :3].T @ part.frame[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)))
    return (1000.0 * float(np.linalg.norm(T[:3, 3] - part.frame[:3, 3])), float(turn),
            1000.0 * float(np.median(np.abs(near - r))))


def _radius_words(r: float, d: np.ndarray, near_mm: float) -> str:
    """What the radius ``r`` (mm) given for points ``d`` (mm) off the path looks like, by the share of the points
    each reading of it puts on the contour (within ``near_mm``): the diameter (r / 2), inches (25.4 r)."""
    for what, radius in (("the diameter", r / 2.0), ("inches", r * INCH_MM)):
        on = float(np.mean(np.abs(d - radius) <= near_mm))
        if on >= ON_SHARE:
            given = (f"{r:g} mm is the diameter? a radius of {radius:.3g} mm" if what == "the diameter" else
                     f"inches? {r:g} in is {radius:.3g} mm, a radius that")
            return f": {given} puts {100 * on:.0f} % of the points on the contour (within {near_mm:g} mm)"
    return ""


def check_units(part: PartMeasurement, cut: TracedCut, r: float, near_mm: float) -> None:
    """A part whose contour is 25.4 or 1000 times smaller (or larger) than the path ``cut`` traced is in the wrong
    unit: DataError naming the likely one. Unless its points, placed by its frame, already lie on the wall (the
    tool radius ``r`` off the path, within ``near_mm``): a few points of a short stretch span little, in any
    unit."""
    trace = cut.trace
    pts = part.points_mm / 1000.0
    size = float(np.max(np.ptp(pts, axis=0)))
    path = float(np.max(np.ptp(cut.c2, axis=0))) + 2 * r
    if size <= 0 or path <= 0:
        return
    if part.frame is not None:
        near, _ = cut.tree.query(cut.in_plane(part.in_base()))
        if 1000.0 * float(np.median(np.abs(near - r))) <= near_mm:
            return
    ratio = path / size
    for unit, factor in UNITS.items():
        for k, name in ((factor, unit), (1.0 / factor, None)):
            if abs(np.log(ratio / k)) < np.log(1.25):
                if name is None:        # the points are larger than the path by the factor
                    raise DataError(f"{part.source}: the measured contour is {1 / ratio:.0f} x larger than the "
                                    f"path the trace {trace.source} cut: the points look like they are in a unit "
                                    f"{factor:g} x smaller than mm (the format is millimetres)")
                raise DataError(f"{part.source}: the measured contour is {ratio:.1f} x smaller than the path the "
                                f"trace {trace.source} cut: the points look like they are in {unit}, not millimetres "
                                f"(docs/part_format.md); multiply them by {factor:g}")
