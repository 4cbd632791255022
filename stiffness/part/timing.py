"""When each point of a part was made: the moment the deflected tool passed it, and the curve's term
(`stiffness.part.rows`'s docstring has the geometry; docs/part.md).

The commanded path passes abeam of a point at the fractional trace row u; the tool that made the point was
the deflected one, which passed there earlier or later by its deflection along the path over the feed,
t* = u - (dX . t) / |dc/du|. On a curved wall the point lies kappa_w d_t^2 / 2 inside what n . dX says. Both
need the deflection, so a model's prediction of it places the points: `when_made(rows, model)`.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .rows import PartRows

CHORD_M = 0.002          # the path's curvature is taken over this length either side of a point


def when_made(rows: PartRows, model, iterations: int = 2) -> PartRows:
    """``rows`` with each point's time, joints and wrench at the moment the deflected tool made it, and the
    curve's term of its deviation (module docstring), from ``model``'s prediction of the deflection."""
    tool = rows.trace_tool
    step = np.gradient(tool, axis=0)                             # dc/du per trace row
    u = rows.u
    d_t = np.zeros(len(u))
    for _ in range(iterations):
        out = _at(rows, u, None)
        data = out.dataset(model.robot, model.input_map(), history_step_s=None)
        pred = model.predict(model.context(data))[:, :3]          # in the rows' axes (n, a x n, a)
        dX = np.empty((len(u), 3))
        dX[np.argsort(out.t, kind="stable")] = np.einsum("nji,nj->ni", data.axes, pred)   # base axes
        d = _interp(step, rows.u)
        speed = np.maximum(np.linalg.norm(d, axis=1), 1e-12)
        d_t = np.einsum("na,na->n", dX / 1000.0, d / speed[:, None])
        u = np.clip(rows.u - d_t / speed, 0.0, len(rows.trace) - 1.0)
    kappa = _curvature(tool, rows.u, rows.normal)
    r = rows.part.tool_radius_mm / 1000.0
    kappa_w = kappa / np.maximum(1.0 + r * kappa, 1e-3)
    return _at(rows, u, kappa_w * d_t**2 / 2.0 * 1000.0)


def _curvature(tool: np.ndarray, u: np.ndarray, n: np.ndarray, chord: float = CHORD_M) -> np.ndarray:
    """The commanded path's curvature at fractional rows ``u`` (1/m), from the points ``chord`` before and
    after along its length (a traced path is a staircase of the PLC's cycle: no derivative of it is smooth),
    signed positive where it bends away from ``n``: kappa = -(A + C - 2 B) . n / chord^2."""
    s = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(tool, axis=0), axis=1))])
    s_u = _interp(s, u)
    keep = np.r_[True, np.diff(s) > 0]                 # arc length strictly rising: a stopped tool adds nothing
    s_k, tool_k = s[keep], tool[keep]

    def at(x):
        return np.column_stack([np.interp(x, s_k, tool_k[:, k]) for k in range(3)])

    A, B, C = at(s_u - chord), at(s_u), at(s_u + chord)
    return -np.einsum("na,na->n", A + C - 2.0 * B, n) / chord**2


def _interp(x: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Rows of ``x`` (per trace row) at fractional rows ``u``, linearly."""
    k0 = np.clip(np.floor(u).astype(int), 0, len(x) - 2)
    w = (u - k0).reshape((-1,) + (1,) * (x.ndim - 1))
    return (1.0 - w) * x[k0] + w * x[k0 + 1]


def _at(rows: PartRows, u: np.ndarray, curve_mm: np.ndarray | None) -> PartRows:
    """``rows`` with time, joints and wrench taken at the fractional trace rows ``u``, and the curve's term."""
    tr = rows.trace
    return dataclasses.replace(rows, t=_interp(tr.time_s, u), q_deg=_interp(tr.commanded_q_deg, u),
                               wrench_base=_interp(rows.smooth_wrench, u), curve_mm=curve_mm)
