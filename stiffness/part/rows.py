"""A part's points read against the trace of its cut: where the tool was, and what loaded it, when it
made each point (docs/part.md).

The cutter's edge makes the surface: a point p of the wall lies the tool radius r from the tool's axis
at the moment the tool passed it. The trace gives the commanded joints q(t) of every cycle, so the
commanded tool centre c(t) (forward kinematics of the TCP) and the tool axis a(t): the trace's cut
(`stiffness.part.contour.traced_cut`), computed once and read by all the checks. The moment a point was
made is the one where the commanded path passes abeam of it: the closest point c(u) of the path (a
fractional cycle index u), in the plane across the tool axis. There

    n = P (p - c(u)) / |P (p - c(u))|,    e = |P (p - c(u))| - r        (P = I - a a^T)

n is the surface normal (from the tool's centre to the wall) and e the normal deviation the cut left:
the arm's deflection along n when it made the point, n . dX(q(u), W(u)) (the joints in the trace already
hold the service's correction, so e is the deflection itself, whatever the correction was). The part's
error against its nominal contour is the same with the nominal path c_nom(u) = FK(q(u) - correction(u)).

When the point was made. The commanded path passes abeam of a point at u, but the tool that made it was
the deflected one, which passed there earlier or later by its deflection along the path over the feed:
t* = u - (dX . t) / |dc/du|. `stiffness.part.timing.when_made` places each point at t* with a model's prediction of dX (the loads
at t* are what deflected the arm then). On a curved wall the point then lies a little inside what n . dX
says: the deflection along the path d_t carries the tool around the curve,

    e = n . dX(t*) - kappa_w d_t^2 / 2,      kappa_w = kappa / (1 + r kappa)

kappa the commanded path's curvature, signed positive where the path bends away from the wall (a few um at
0.5 mm along a 35 mm circle), and adds the term to the row's measured deviation.

The wrench is the trace's, smoothed without lag (a zero-phase low-pass at ``smooth_hz``, 10 Hz by
default): the arm does not follow the tooth passing, and the joint torque's ripple and the sensor's noise
(a few Nm) would otherwise flip a hysteresis state back and forth near each reversal of the torque, where
the arm's own state flips once.

Each point becomes one row of a `Dataset`: the TCP at q(u), loaded by the trace's wrench at u (turned back
to the sensor's axes), measured in axes of its own (`Dataset.axes`: n, a x n, a) with only the first
component, e, measured. Rows of the trace between the points, with nothing measured, carry the load's
history for effects that have one (hysteresis).

Checks, each naming the file and the line: points far from where the tool went; a file whose points fit
the traced path only after scaling by 25.4 or 1000 (inches, metres); a trace that never passes the
contour at all. A point the tool passed twice (the overlap of a closed contour's entry and exit: another
pass came within `contour.PASS_MARGIN_MM` as close to it as the closest one) is left out and named: which pass made
it cannot be told. So is a point made while the trace lost rows (a gap in its cycle count, `Trace.gaps`), or
within GAP_MARGIN_MM of the path of them: where the arm was and what loaded it then is not known, and the
path across the gap is a chord. The notes name each gap (its cycles, its time, how many rows) and the points
left out by file line (`stiffness.part.left_out`); the wrench is smoothed on each side of a gap on its own.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from functools import partial

import numpy as np
from scipy import signal

from ..data.measurements import Dataset
from ..data.part_points import PartMeasurement
from ..data.trace_file import Gap, Trace
from ..errors import DataError, Problems
from ..kinematics.robot import Robot
from .contour import WALL_HEIGHT_MM, Passing, TracedCut, plane_basis, traced_cut
from .left_out import IN_GAP, JUMP, TWICE, Jump, LeftOut, left_out_lines
from .suspects import causes, check_units, explain, frame_fit

NEAR_MM = 3.0            # a point farther than this from r off the traced path is not on the contour: more
                         # than an arm deflects under a cut (a few tenths of a mm to about 2 mm)
HISTORY_STEP_S = 0.005   # the load history between points, kept at this step
SMOOTH_HZ = 10.0         # the trace's wrench, low-passed without lag (the arm's first modes are 7-20 Hz)


@dataclass
class PartRows:
    """A part's points, each at the moment the tool made it (arrays over the used points)."""

    part: PartMeasurement
    trace: Trace
    label: str
    used: np.ndarray             # (N points,) bool: matched to one pass of the tool
    u: np.ndarray                # fractional trace row of each used point
    t: np.ndarray                # trace time_s at u
    point: np.ndarray            # (n, 3) the point in the base, m
    tool: np.ndarray             # (n, 3) the commanded tool centre c(u), m
    normal: np.ndarray           # (n, 3) from the tool's centre to the wall
    axis: np.ndarray             # (n, 3) the tool axis
    deviation_mm: np.ndarray     # e: the deflection along n the cut left
    nominal_mm: np.ndarray       # the error against the nominal contour, along n
    q_deg: np.ndarray            # (n, 6) at u
    wrench_base: np.ndarray      # (n, 6) the trace's wrench at u, smoothed (base axes, moment about the sensor origin)
    correction_mm: np.ndarray    # how far the service's correction moved the tool along n
    frame: np.ndarray            # (4, 4) base <- part used (the file's, or the best fit's)
    smooth_wrench: np.ndarray    # (N trace, 6) the trace's wrench, smoothed
    trace_tool: np.ndarray       # (N trace, 3) the commanded tool centre of every trace row, m
    notes: list[str] = field(default_factory=list)
    curve_mm: np.ndarray | None = None    # kappa_w d_t^2 / 2 (`timing.when_made`); None: not placed yet
    left_out: list[LeftOut] = field(default_factory=list)    # the points not used, and why
    gaps: list[Gap | Jump] = field(default_factory=list)     # where the trace is blind: rows lost, joints jumped

    @property
    def measured_mm(self) -> np.ndarray:
        """What a row measures of n . dX: the deviation plus the curve's term once `when_made` placed it."""
        return self.deviation_mm if self.curve_mm is None else self.deviation_mm + self.curve_mm

    @property
    def arc_deg(self) -> np.ndarray:
        """Each used point's position along the contour: its angle about the contour's centroid in the plane
        across the tool axis (deg, 0..360, in the order the tool went)."""
        a = self.axis.mean(axis=0)
        e1, e2 = plane_basis(a / np.linalg.norm(a))
        d = self.point - self.point.mean(axis=0)
        ang = np.degrees(np.arctan2(d @ e2, d @ e1))
        order = np.argsort(self.u)
        unwrapped = np.empty_like(ang)
        unwrapped[order] = np.degrees(np.unwrap(np.radians(ang[order])))
        return unwrapped - unwrapped[order[0]] + (ang[order[0]] % 360.0)

    def dataset(self, robot: Robot, input_map: np.ndarray | None = None,
                history_step_s: float | None = HISTORY_STEP_S) -> Dataset:
        """The points as rows of a campaign (TCP, measured along n only), and the trace between them as
        rows measuring nothing (the load's history), in time order; configuration ``label``.

        ``input_map``: the model's L (W_true = L W_measured; `StiffnessModel.input_map`): the trace's wrench
        is the true one in base axes, so a row's sensor wrench is L^-1 of it in the sensor's axes.
        ``history_step_s`` None: the points alone."""
        tr = self.trace
        lo, hi = float(self.t.min()), float(self.t.max())
        first = np.searchsorted(tr.time_s, lo - 0.2)
        rows = np.arange(first, np.searchsorted(tr.time_s, hi, side="right"))
        keep = (rows[np.r_[True, np.diff(np.floor(tr.time_s[rows] / history_step_s)) > 0]]
                if history_step_s is not None else rows[:0])
        t = np.concatenate([self.t, tr.time_s[keep]])
        q = np.concatenate([self.q_deg, tr.commanded_q_deg[keep]])
        wb = np.concatenate([self.wrench_base, self.smooth_wrench[keep]])
        n = len(self.t)
        defl = np.full((len(t), 6), np.nan)
        defl[:n, 0] = self.measured_mm
        axes = np.broadcast_to(np.eye(3), (len(t), 3, 3)).copy()
        axes[:n, 0] = self.normal
        axes[:n, 2] = self.axis
        axes[:n, 1] = np.cross(self.axis, self.normal)
        order = np.argsort(t, kind="stable")
        F = robot.frames(np.radians(q))
        R_s = robot.sensor_pose(F)[:, :3, :3]
        w = np.concatenate([np.einsum("nji,nj->ni", R_s, wb[:, :3]), np.einsum("nji,nj->ni", R_s, wb[:, 3:])], 1)
        if input_map is not None:
            w = w @ np.linalg.inv(input_map).T
        line = np.concatenate([self.part.lines[self.used], np.full(len(keep), -1)])
        return Dataset(t[order], np.full(len(t), self.label), q[order], w[order], np.full(len(t), 6),
                       defl[order], line[order], self.part.source, axes=axes[order])


def read_against(part: PartMeasurement, trace: Trace, robot: Robot, label: str = "part",
                 best_fit: bool = False, near_mm: float = NEAR_MM, smooth_hz: float = SMOOTH_HZ) -> PartRows:
    """Match every point of ``part`` to the moment its ``trace`` passed it (the module's docstring): `read_cut`
    on the trace's cut."""
    return read_cut(part, traced_cut(trace, robot), robot, label, best_fit, near_mm, smooth_hz)


def read_cut(part: PartMeasurement, cut: TracedCut, robot: Robot, label: str = "part",
             best_fit: bool = False, near_mm: float = NEAR_MM, smooth_hz: float = SMOOTH_HZ) -> PartRows:
    """Match every point of ``part`` to the moment the trace of ``cut`` passed it (the module's docstring).

    ``best_fit``: place the part by a best fit to the traced path instead of (or, with a part frame,
    starting from) its part frame: for a part without a datum. The fit hides a constant offset of the
    contour (a rigid shift of all points), and the notes say so. ``near_mm``: how far from the tool radius
    off the traced path a point may lie and still be on the contour (the largest deflection expected).
    ``smooth_hz``: the zero-phase low-pass of the trace's wrench (0: none).
    """
    trace = cut.trace
    r = part.tool_radius_mm / 1000.0
    check_units(part, cut, r, near_mm)
    if best_fit or part.frame is None:
        if not best_fit:
            raise DataError(f"{part.source}: no part_frame: the points cannot be placed in the robot's base; give "
                            "the fixture's calibration as '# part_frame: {xyz_mm: [...], rpy_deg: [...]}', or "
                            "--best-fit (which hides a constant offset of the contour)")
        frame = _best_fit(part, cut, r)
    else:
        frame = part.frame
    p = part.in_base(frame)
    height = 1000.0 * float(np.median(p @ cut.a) - cut.height)
    if abs(height) > WALL_HEIGHT_MM:
        raise DataError(f"{part.source}: the points lie {height:+.1f} mm along the tool axis from the tool centre's "
                        f"path (median), where a wall the tool cut is within {WALL_HEIGHT_MM:g} mm of it: the points' "
                        "coordinates or the part_frame are that far off along the tool axis (metres for mm?)")
    def why_far(near: np.ndarray, some: bool = False) -> str:
        """Why the points lie off the path: all of them (the refusal), or ``some`` (the causes alone)."""
        fit = None if best_fit or part.frame is None else (lambda: frame_fit(part, _best_fit(part, cut, r), cut, r))
        span = 1000.0 * (float(np.max(np.ptp(cut.c2, axis=0))) + 2 * r)
        return (causes if some else partial(explain, trace_source=trace.source))(
            part, near_m=near, path_span_mm=span, fit=fit, near_mm=near_mm)

    rows = rows_of(part, p, cut.passing(cut.in_plane(p), r, near_mm / 1000.0), cut, robot, label, frame,
                   near_mm, smooth_hz, why_far)
    if best_fit:
        rows.notes.append("--best-fit placed the part by its own points: a constant offset of the contour (the mean "
                          "deflection in the plane, a rigid shift of every point) is hidden in the placement and "
                          "neither shown nor learned")
    return rows


def rows_of(part: PartMeasurement, p: np.ndarray, passing: Passing, cut: TracedCut, robot: Robot, label: str,
            frame: np.ndarray, near_mm: float = NEAR_MM, smooth_hz: float = SMOOTH_HZ, why_far=None) -> PartRows:
    """The points of ``part``, in the base at ``p`` (m) through ``frame``, at the moments the trace of ``cut``
    passed them (``passing``, `TracedCut.passing`): those the tool passed once, where the trace saw it, as rows;
    the others left out and named, or refused by line (`_match`, ``why_far``)."""
    trace, r, blind = cut.trace, part.tool_radius_mm / 1000.0, cut.blind
    used, u_of, left = _match(part, cut, passing, r, near_mm, blind, why_far)
    for k in np.nonzero(used & (passing.blind >= 0))[0]:
        left[k] = int(passing.blind[k])
    used &= passing.blind < 0
    left_out = [LeftOut(part.source, int(part.lines[k]), part.labels[k], _why(blind[v]) if isinstance(v, int) else v)
                for k, v in sorted(left.items())]
    hit = set(left.values())
    blind = [b for k, b in enumerate(blind) if isinstance(b, Gap) or k in hit]     # a jump no point was near: silent
    out = (_rows(part, cut, robot, label, used, u_of[used], p[used], r, frame, smoothed(trace, smooth_hz, blind))
           if used.sum() >= 3 else None)
    lines = left_out_lines(left_out)
    if out is None:
        raise DataError(f"{part.source}: only {int(used.sum())} point(s) lie where the tool passed once"
                        + "".join(f"; {n}" for n in lines))
    out.left_out, out.gaps, out.notes = left_out, blind, [b.text(trace.source) for b in blind] + lines
    return out


def _why(blind: Gap | Jump) -> str:
    return IN_GAP if isinstance(blind, Gap) else JUMP


def _match(part: PartMeasurement, cut: TracedCut, passing: Passing, r: float, near_mm: float,
           blind: list[Gap | Jump], why_far=None) -> tuple[np.ndarray, np.ndarray, dict[int, str | int]]:
    """Which points of ``part`` are used, at the fractional trace rows where the path of ``cut`` passes abeam of
    them (``passing``), and why each other one is left out (a reason, or the index of the ``blind`` span it lies
    beside). A point far off the path where the trace is blind is left out for that; far off elsewhere, it is
    refused by line; a point another pass came within PASS_MARGIN_MM as close to is left out (passed twice)."""
    near, row = passing.near, passing.row
    at = {n: k for k, b in enumerate(blind) for n in range(b.row - getattr(b, "still", 0), b.row + 2)}
    beside_gap = np.isin(row, list(at))
    far = np.abs(near - r) > near_mm / 1000.0
    if (far & ~beside_gap).mean() > 0.5:            # the causes, each with its evidence (`suspects.explain`)
        raise DataError(why_far(near) if why_far is not None else
                        f"{part.source}: the trace {cut.trace.source} never passes the measured contour")
    problems, left = Problems(), {}
    for k in range(len(near)):
        if far[k] and beside_gap[k]:
            left[k] = at[int(row[k])]
        elif far[k]:
            problems.add(f"{part.where(k)}: the point lies {1000 * (near[k] - r):+.2f} mm off where the tool passed "
                         f"(tolerance {near_mm:g} mm): it is not on the machined contour")
        elif passing.passes[k] > 1:
            left[k] = TWICE
    if problems:
        why = f". {why_far(near, some=True)}" if why_far is not None and problems.count >= max(3, 0.1 * len(near)) else ""
        raise DataError(f"{part.source}: {problems.count} point(s) are not on the contour the trace cut; "
                        f"nothing was used{why}", problems)
    used = ~far & (passing.passes == 1)
    return used, np.where(used, passing.u, np.nan), left


def smoothed(trace: Trace, cutoff_hz: float, gaps: list[Gap | Jump] | None = None) -> np.ndarray:
    """The trace's wrench low-passed without lag (Butterworth, order 2, forward and backward) at ``cutoff_hz``,
    each run of rows between ``gaps`` (rows the trace lost, joints that jumped) on its own; the trace's own where
    the cutoff is 0 or a run too short."""
    w = trace.wrench_base.copy()
    dt = float(np.median(np.diff(trace.time_s))) if len(trace) > 1 else 0.0
    if cutoff_hz <= 0 or dt <= 0 or cutoff_hz >= 0.5 / dt:
        return w
    sos = signal.butter(2, cutoff_hz, fs=1.0 / dt, output="sos")
    ends = [0] + [g.row + 1 for g in gaps or []] + [len(w)]
    for lo, hi in itertools.pairwise(ends):
        if hi - lo >= 30:
            w[lo:hi] = signal.sosfiltfilt(sos, w[lo:hi], axis=0)
    return w


def _rows(part, cut: TracedCut, robot, label, used, u, p, r, frame, wrench) -> PartRows:
    """The used points at their fractional trace rows ``u``: normals, deviations, and the trace between."""
    trace, a = cut.trace, cut.a
    k0 = np.clip(np.floor(u).astype(int), 0, len(trace) - 2)
    w = (u - k0)[:, None]

    def at(x):
        return (1.0 - w) * x[k0] + w * x[k0 + 1]

    c = at(cut.tool)
    d = (p - c) @ (np.eye(3) - np.outer(a, a))
    dist = np.linalg.norm(d, axis=1)
    n = d / dist[:, None]
    q = at(trace.commanded_q_deg)
    c_nom = robot.frames(np.radians(q - at(trace.correction_deg)))[:, 7, :3, 3]
    shift = np.einsum("na,na->n", n, c - c_nom) * 1000.0
    e = (dist - r) * 1000.0
    return PartRows(part, trace, label, used, u, at(trace.time_s[:, None])[:, 0], p, c, n,
                    np.broadcast_to(a, c.shape).copy(), e, e + shift, q, at(wrench), shift, frame, wrench, cut.tool)


def _best_fit(part: PartMeasurement, cut: TracedCut, r: float, iterations: int = 30) -> np.ndarray:
    """base <- part by a fit of the points to the traced path of ``cut`` offset by r (in-plane rotation and shift,
    and the shift along the axis to the path's height): iterative closest points."""
    e1, e2, a, c2 = cut.e1, cut.e2, cut.a, cut.c2
    T = np.eye(4) if part.frame is None else part.frame.copy()
    pts = part.points_mm / 1000.0
    if part.frame is None:          # start with the part's axes as the base's, its centroid on the path's
        T[:3, 3] = cut.c.mean(axis=0) - pts.mean(axis=0)
    for _ in range(iterations):
        p = pts @ T[:3, :3].T + T[:3, 3]
        p2 = cut.in_plane(p)
        dist, j = cut.tree.query(p2)
        target = c2[j] + (p2 - c2[j]) * (r / np.maximum(dist, 1e-12))[:, None]   # r from the path, abeam
        R2, t2 = _rigid_2d(p2, target)
        step = np.eye(4)
        B = np.column_stack([e1, e2, a])
        R3 = np.eye(3)
        R3[:2, :2] = R2
        step[:3, :3] = B @ R3 @ B.T
        step[:3, 3] = t2[0] * e1 + t2[1] * e2
        T = step @ T
        if np.linalg.norm(t2) < 1e-9 and abs(np.arctan2(R2[1, 0], R2[0, 0])) < 1e-9:
            break
    return T


def _rigid_2d(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """R (2, 2), t (2,) minimising |R x + t - y| (Kabsch in the plane)."""
    mx, my = x.mean(axis=0), y.mean(axis=0)
    U, _, Vt = np.linalg.svd((x - mx).T @ (y - my))
    D = np.diag([1.0, np.sign(np.linalg.det(Vt.T @ U.T))])
    R = Vt.T @ D @ U.T
    return R, my - R @ mx
